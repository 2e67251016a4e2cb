#include "photorig/daemon/rig_devices.h"

#include "photorig/sim/devices.h"

namespace photorig::daemon {

RigDevices MakeRigDevices(const RigConfig& rig, const Recipe* recipe) {
  RigDevices devices;
  if (rig.IsSimulated()) {
    sim::WorldConfig world;
    world.seed = rig.sim->seed;
    world.sensor = rig.sim->sensor;
    world.scene = rig.sim->scene;
    if (recipe && recipe->sim_scene)
      world.scene = ParseScene(*recipe->sim_scene, rig.camera.width * rig.camera.pixel_pitch_mm);
    world.camera = {rig.camera.width, rig.camera.height, rig.camera.pixel_pitch_mm};
    for (const LedConfig& led : rig.lights.leds) world.lights.push_back({led.direction, led.intensity});
    devices.world = std::make_shared<sim::World>(std::move(world));
  }
  // LoadRigConfig accepts only known drivers, so "sim" is the one left today.
  devices.lights = std::make_unique<sim::SimLightDome>(rig.lights.id, devices.world);
  devices.camera = std::make_unique<sim::SimCamera>(rig.camera.id, devices.world);
  return devices;
}

}  // namespace photorig::daemon
