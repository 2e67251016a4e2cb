#include "photorig/daemon/rig_devices.h"

#include "photorig/daemon/device_factory.h"

#include <Eigen/Geometry>

#include <cmath>
#include <random>

namespace photorig::daemon {
namespace {

// Each light turned about the object origin off its nominal direction by a
// Gaussian offset in the tangent plane whose RMS magnitude is rms_deg;
// deterministic in the seed.
void TiltLights(double rms_deg, std::uint64_t seed, std::vector<sim::Light>* lights) {
  if (rms_deg <= 0.0) return;
  std::mt19937_64 rng(seed ^ 0x5eedD1ec7ULL);
  std::normal_distribution<double> offset(0.0, rms_deg * M_PI / 180.0 / std::sqrt(2.0));
  for (sim::Light& light : *lights) {
    const Eigen::Vector3d d = light.direction.normalized();
    const Eigen::Vector3d u = d.unitOrthogonal(), v = d.cross(u);
    const Eigen::Vector2d tilt(offset(rng), offset(rng));
    if (tilt.norm() == 0.0) continue;
    const Eigen::AngleAxisd rotation(tilt.norm(), (tilt.x() * v - tilt.y() * u).normalized());
    light.direction = rotation * d;
    if (light.position_mm) {  // a near LED swings about the object origin, still aimed at it
      light.position_mm = rotation * *light.position_mm;
      light.axis = rotation * light.axis;
    }
  }
}

}  // namespace

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
    TiltLights(rig.sim->led_direction_error_deg, rig.sim->seed, &world.lights);
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
