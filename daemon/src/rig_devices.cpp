#include "photorig/daemon/rig_devices.h"

#include "photorig/daemon/device_factory.h"
#include "photorig/sim/light_errors.h"

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
    world.gonioreflectometer = rig.kind == "gonioreflectometer";
    for (const LedConfig& led : rig.lights.leds) {
      sim::Light light(led.direction, led.intensity);
      if (led.position_mm) {
        light.position_mm = led.position_mm;
        light.axis = -led.position_mm->normalized();  // aimed at the object
      }
      world.lights.push_back(light);
    }
    sim::PerturbLights({rig.sim->led_direction_error_deg, rig.sim->led_intensity_error_pct}, rig.sim->seed,
                       &world.lights);
    world.ambient = rig.sim->ambient;
    devices.world = std::make_shared<sim::World>(std::move(world));
  }
  const DeviceContext context{rig, devices.world};
  devices.lights = MakeLightController(context);
  devices.camera = MakeCamera(context);
  devices.trigger = MakeTriggerOutput(context);
  devices.motion = MakeMotion(context);
  return devices;
}

}  // namespace photorig::daemon
