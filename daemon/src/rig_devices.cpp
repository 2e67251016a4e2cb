#include "photorig/daemon/rig_devices.h"

#include "photorig/daemon/device_factory.h"

namespace photorig::daemon {

RigDevices MakeRigDevices(const RigConfig& rig, const Recipe* recipe) {
  RigDevices devices;
  if (rig.IsSimulated()) {
    sim::WorldConfig world;
    world.seed = rig.sim->seed;
    world.sensor = rig.sim->sensor;
    world.camera_faults = rig.sim->camera_faults;
    world.light_faults = rig.sim->light_faults;
    world.scene = rig.sim->scene;
    if (recipe && recipe->sim_scene)
      world.scene = ParseScene(*recipe->sim_scene, rig.camera.width * rig.camera.pixel_pitch_mm);
    world.camera = {rig.camera.width, rig.camera.height, rig.camera.pixel_pitch_mm};
    for (const LedConfig& led : rig.lights.leds) world.lights.push_back({led.direction, led.intensity});
    devices.world = std::make_shared<sim::World>(std::move(world));
  }
  const DeviceContext context{rig, devices.world};
  devices.lights = MakeLightController(context);
  devices.camera = MakeCamera(context);
  return devices;
}

}  // namespace photorig::daemon
