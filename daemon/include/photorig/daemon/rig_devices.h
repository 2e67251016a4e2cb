#pragma once
// Opens the devices a rig describes, through the driver interfaces.

#include "photorig/daemon/device_factory.h"
#include "photorig/daemon/recipe.h"
#include "photorig/daemon/rig_config.h"
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
RigDevices MakeRigDevices(const RigConfig& rig, const Recipe* recipe);

}  // namespace photorig::daemon
