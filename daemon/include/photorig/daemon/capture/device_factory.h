#pragma once
// Builds (never opens) the devices a loaded rig describes. The rig's driver
// settings were parsed and checked by LoadRigConfig, so building a device
// finds no configuration errors; what can still fail here is the outside
// world (e.g. a simulated Modbus controller that cannot bind its port).
//
// Adding a driver: its settings in rigconfig/ (photorig/config/driver_options.h),
// its maker in capture/internal/device_makers.h and its entry in the makers'
// table of src/capture/device_factory.cpp.

#include "photorig/daemon/capture/device_context.h"
#include "photorig/drivers/camera.h"
#include "photorig/drivers/trigger_output.h"
#include "photorig/drivers/light_controller.h"

#include <memory>
#include <string>
#include <vector>

namespace photorig::daemon {

std::unique_ptr<drivers::LightController> MakeLightController(const DeviceContext& context);
std::unique_ptr<drivers::Camera> MakeCamera(const DeviceContext& context);
// The output that fires a hardware-triggered camera; null for software triggers.
std::unique_ptr<drivers::TriggerOutput> MakeTriggerOutput(const DeviceContext& context);

// Whether the rig's lights are a controller outside this process, which can
// still be lit from an earlier process (one killed mid-exposure, a power cut
// of the PC). Simulated lights, and a Modbus controller served in-process,
// start dark with the process.
bool LightsOutliveTheProcess(const config::RigConfig& rig);
// Opens and closes such a controller: opening switches every output off and
// closing leaves them off. photorigd does it as it starts, and `photorig
// lights off` (systemd's ExecStopPost) after photorigd ended, however it
// ended. Does nothing for lights that do not outlive the process.
Status DarkenLights(const config::RigConfig& rig);

MotionRig MakeMotion(const DeviceContext& context);

}  // namespace photorig::daemon
