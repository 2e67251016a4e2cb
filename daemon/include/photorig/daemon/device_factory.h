#pragma once
// The table of device drivers a rig YAML may name. Each entry builds (never
// opens) a device from the rig's common settings plus its driver-specific
// `options:` map; configuration errors are ConfigError naming file:line:column.
//
// Adding a driver: one entry in src/device_factory.cpp.

#include "photorig/daemon/rig_config.h"
#include "photorig/drivers/camera.h"
#include "photorig/drivers/trigger_output.h"
#include "photorig/drivers/light_controller.h"
#include "photorig/sim/world.h"

#include <memory>
#include <string>
#include <vector>

namespace photorig::daemon {

// `world` is non-null for rigs with a `sim:` section; simulated devices render
// from it and simulated protocol peers serve it.
struct DeviceContext {
  const RigConfig& rig;
  std::shared_ptr<sim::World> world;
};

bool IsKnownLightDriver(const std::string& name);
bool IsKnownCameraDriver(const std::string& name);
std::string LightDriverNames();   // "sim, ..." for error messages
std::string CameraDriverNames();

std::unique_ptr<drivers::LightController> MakeLightController(const DeviceContext& context);
std::unique_ptr<drivers::Camera> MakeCamera(const DeviceContext& context);
// The output that fires a hardware-triggered camera; null for software triggers.
std::unique_ptr<drivers::TriggerOutput> MakeTriggerOutput(const DeviceContext& context);

// A gonioreflectometer's axes and the Goniometer that moves them under the
// rig's separation constraints. Empty for a rig without `motion:`.
struct MotionRig {
  std::vector<std::unique_ptr<drivers::Motion>> axes;
  std::unique_ptr<drivers::Goniometer> goniometer;
};
MotionRig MakeMotion(const DeviceContext& context);

}  // namespace photorig::daemon
