#include "photorig/config/sim.h"

#include "photorig/sim/light_errors.h"

#include <stdexcept>

namespace photorig::config {

sim::WorldConfig MakeWorldConfig(const RigConfig& rig, const sim::Scene& scene) {
  if (!rig.sim) throw std::logic_error("rig '" + rig.name + "' has no sim: section");
  sim::WorldConfig world;
  world.seed = rig.sim->seed;
  world.sensor = rig.sim->sensor;
  world.camera_faults = rig.sim->camera_faults;
  world.light_faults = rig.sim->light_faults;
  world.scene = scene;
  world.camera = {rig.camera.width, rig.camera.height, rig.camera.pixel_pitch_mm};
  if (rig.camera.projection == solvers::camera::Projection::kPinhole) {
    const solvers::camera::PinholeLens& lens = rig.camera.pinhole;
    world.camera.projection = sim::CameraModel::Projection::kPinhole;
    world.camera.fx = lens.fx_px;
    world.camera.fy = lens.fy_px;
    // The simulator measures from the image's corner, OpenCV from the first pixel's centre.
    world.camera.cx = lens.cx_px + 0.5;
    world.camera.cy = lens.cy_px + 0.5;
    world.camera.distortion = lens.distortion;
    world.camera.distance_mm = lens.distance_mm;
  }
  world.gonioreflectometer = rig.kind == RigKind::kGonioreflectometer;
  if (rig.reference_target && rig.reference_target->pose.sample_changer_deg)
    world.reference_target = sim::ReferenceTarget{rig.reference_target->albedo,
                                                  *rig.reference_target->pose.sample_changer_deg};
  for (const LedConfig& led : rig.lights.leds) {
    sim::Light light(led.direction, led.intensity);
    if (led.position_mm) {
      light.position_mm = led.position_mm;
      light.axis = led.EmissionAxis();
      light.cos_exponent = led.cos_exponent;
      light.emitter_radius_mm = rig.sim->led_emitter_radius_mm;
    }
    world.lights.push_back(light);
  }
  sim::PerturbLights({rig.sim->led_direction_error_deg, rig.sim->led_intensity_error_pct}, rig.sim->seed,
                     &world.lights);
  world.ambient = rig.sim->ambient;
  const sim::ColorCamera color = ColorSceneResponses(rig.sim->color, world.scene.albedo);
  if (world.scene.albedo.paints.size() == 2) {
    // The texture's numbers become the paints' luminance: what a monochrome
    // camera sees of them, and the monochrome ground truth (albedo.tiff).
    world.scene.albedo.low = color.truth_low_srgb.dot(LuminanceOfLinearSrgb());
    world.scene.albedo.high = color.truth_high_srgb.dot(LuminanceOfLinearSrgb());
  }
  if (rig.camera.mosaic != "mono") {
    world.color = color;
    world.color.mosaic = rig.camera.mosaic;
  }
  return world;
}

}  // namespace photorig::config
