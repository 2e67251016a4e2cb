#pragma once
// What the simulator is told by a rig's `sim:` section and a recipe's
// `sample.sim_scene:`: the scene, and the World both describe. The simulator
// tools read rigs through these, not through the daemon.

#include "photorig/config/rig.h"
#include "photorig/config/scene.h"
#include "photorig/config/sim_color.h"
#include "photorig/sim/scene.h"
#include "photorig/sim/world.h"

namespace photorig::config {

// The simulated World of a rig with a `sim:` section, showing `scene`: LEDs
// where the rig puts them (tilted by sim.led_direction_error_deg), the
// camera's frame, the sensor and the injected faults.
sim::WorldConfig MakeWorldConfig(const RigConfig& rig, const sim::Scene& scene);

}  // namespace photorig::config
