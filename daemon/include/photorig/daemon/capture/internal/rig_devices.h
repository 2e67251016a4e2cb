#pragma once
// Opens the devices a rig describes, through the driver interfaces.

#include "photorig/daemon/capture/device_factory.h"
#include "photorig/config/recipe.h"
#include "photorig/config/solve_requests.h"
#include "photorig/config/rig.h"
#include "photorig/config/sim.h"
#include "photorig/config/yaml_node.h"
#include "photorig/drivers/camera.h"
#include "photorig/drivers/light_controller.h"
#include "photorig/sim/world.h"

#include <memory>

namespace photorig::daemon {

struct RigDevices {
  std::unique_ptr<drivers::LightController> lights;
  std::unique_ptr<drivers::Camera> camera;
  std::unique_ptr<drivers::TriggerOutput> trigger;  // hardware-triggered cameras only
  std::shared_ptr<sim::World> world;  // simulated rigs only: the ground truth lives here
  MotionRig motion;                   // gonioreflectometers only
};

// Builds (but does not open) the rig's devices. `recipe` may replace the
// simulated scene. Configuration errors were all found when the rig and the
// recipe were loaded; this throws only when the outside world refuses (a
// simulated peer that cannot serve, a scene file gone since).
RigDevices MakeRigDevices(const config::RigConfig& rig, const config::Recipe* recipe);

}  // namespace photorig::daemon
