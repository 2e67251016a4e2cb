#pragma once
// What the simulator is told by a rig's `sim:` section and a recipe's
// `sample.sim_scene:`: the scene, and the World both describe. The simulator
// tools read rigs through these, not through the daemon.

#include "photorig/config/rig.h"
#include "photorig/config/yaml_node.h"
#include "photorig/sim/scene.h"
#include "photorig/sim/world.h"

namespace photorig::config {

// Parses a `scene:` map (a rig's sim.scene, a recipe's sample.sim_scene).
// Sizes the map leaves out are fractions of the frame width, so the scene is
// parsed for the camera that will see it. Files it names (depth maps, meshes,
// BRDF tables) are read now. Throws ConfigError.
sim::Scene ParseScene(const YamlNode& node, double frame_width_mm);

// The frame width in mm of the rig's camera (width x pixel pitch).
double FrameWidthMm(const RigConfig& rig);

// The simulated World of a rig with a `sim:` section, showing `scene`: LEDs
// where the rig puts them (tilted by sim.led_direction_error_deg), the
// camera's frame, the sensor and the injected faults.
sim::WorldConfig MakeWorldConfig(const RigConfig& rig, const sim::Scene& scene);

}  // namespace photorig::config
