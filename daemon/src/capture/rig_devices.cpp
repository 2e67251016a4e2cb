#include "photorig/daemon/capture/internal/rig_devices.h"

#include "photorig/daemon/capture/device_factory.h"

namespace photorig::daemon {

RigDevices MakeRigDevices(const config::RigConfig& rig, const config::Recipe* recipe) {
  RigDevices devices;
  if (rig.IsSimulated())
    devices.world = std::make_shared<sim::World>(
        config::MakeWorldConfig(rig, recipe && recipe->sim_scene ? *recipe->sim_scene : rig.sim->scene));
  const DeviceContext context{rig, devices.world};
  devices.lights = MakeLightController(context);
  devices.camera = MakeCamera(context);
  devices.trigger = MakeTriggerOutput(context);
  devices.motion = MakeMotion(context);
  return devices;
}

}  // namespace photorig::daemon
