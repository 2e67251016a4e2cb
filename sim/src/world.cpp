#include "photorig/sim/world.h"

#include <stdexcept>

namespace photorig::sim {
namespace {

const WorldConfig& Validated(const WorldConfig& config) {
  std::string why;
  if (!config.camera.IsValid(&why)) throw std::invalid_argument("simulated camera: " + why);
  if (!config.scene.IsValid(&why)) throw std::invalid_argument("simulated scene: " + why);
  if (config.scene.shape == Scene::Shape::kMesh && config.camera.projection != CameraModel::Projection::kOrthographic)
    throw std::invalid_argument("simulated scene: meshes are rasterised orthographically only");
  if (config.gonioreflectometer && config.scene.shape != Scene::Shape::kPhantom) CheckGonioScene(config.scene);
  if (config.scene.shape == Scene::Shape::kPhantom &&
      (!config.gonioreflectometer || config.camera.projection != CameraModel::Projection::kOrthographic))
    throw std::invalid_argument("simulated scene: a phantom sits on a gonioreflectometer's turntable, seen orthographically");
  if (!config.ambient.IsValid(&why)) throw std::invalid_argument("simulated ambient light: " + why);
  return config;
}

}  // namespace

World::World(WorldConfig config)
    : config_(Validated(config)),
      surface_(SampleSurface(config_.scene, config_.camera)),
      brdf_(config_.scene.material.MakeBrdf(config_.scene.albedo.high)),
      // The sweep needs the heightfield on the pixel grid, i.e. an orthographic view.
      cast_shadows_(config_.scene.cast_shadows && config_.scene.IsHeightfield() && surface_.height_on_pixel_grid),
      levels_(config_.lights.size(), 0.0) {
  // The sky's shape is fixed, only its level follows the LEDs: one map serves every frame.
  if (config_.ambient.IsOn() && !config_.gonioreflectometer && config_.scene.shape != Scene::Shape::kVolume)
    sky_response_ = RenderSkyResponse(surface_, *brdf_, config_.ambient.samples, config_.seed);
}

void World::SetLevels(std::vector<double> levels) {
  std::lock_guard lock(mutex_);
  levels_ = std::move(levels);
}

std::vector<double> World::levels() const {
  std::lock_guard lock(mutex_);
  return levels_;
}

void World::SetArm(const std::string& axis, double position_deg) {
  std::lock_guard lock(mutex_);
  if (axis == "light_arm") arms_.light_arm_deg = position_deg;
  else if (axis == "camera_arm") arms_.camera_arm_deg = position_deg;
  else if (axis == "sample_rotation") arms_.sample_rotation_deg = position_deg;
  else if (axis == "sample_changer") arms_.sample_changer_deg = position_deg;
  else throw std::invalid_argument("simulated gonioreflectometer has no axis '" + axis + "'");
}

ArmAngles World::arms() const {
  std::lock_guard lock(mutex_);
  return arms_;
}

void World::ConnectTriggerInput(std::function<void()> on_pulse) {
  std::lock_guard lock(trigger_mutex_);
  trigger_input_ = std::move(on_pulse);
}

void World::DisconnectTriggerInput() {
  std::lock_guard lock(trigger_mutex_);
  trigger_input_ = nullptr;
}

bool World::PulseTriggerInput() {
  std::lock_guard lock(trigger_mutex_);
  if (!trigger_input_) return false;
  trigger_input_();
  return true;
}

std::vector<double> World::EmittedLevels() const {
  std::vector<double> emitted = levels();
  for (const auto& [channel, fraction] : config_.light_faults.dim_channels)
    if (channel >= 0 && channel < static_cast<int>(emitted.size())) emitted[channel] *= fraction;
  return emitted;
}

cv::Mat World::RenderRadiance() const {
  const std::vector<double> emitted = EmittedLevels();
  if (config_.scene.shape == Scene::Shape::kPhantom)
    return RenderPhantomTransmission(config_.scene, config_.camera, config_.lights, emitted, arms());
  if (config_.gonioreflectometer)
    return RenderGonioRadiance(config_.scene, *brdf_, config_.camera, config_.lights, emitted, arms());
  // The backlight belongs to the scene, not to the dome: it is always on.
  if (config_.scene.shape == Scene::Shape::kVolume)
    return RenderTransmission(surface_.line_integrals, config_.scene.backlight_radiance);
  cv::Mat radiance = sim::RenderRadiance(surface_, *brdf_, cast_shadows_, config_.lights, emitted);
  if (config_.scene.interreflection_samples > 0)
    radiance += RenderOneBounce(surface_, *brdf_, radiance, config_.scene.interreflection_samples, config_.seed);
  if (!sky_response_.empty()) {
    double sky_irradiance = config_.ambient.stray_irradiance;
    for (std::size_t k = 0; k < emitted.size() && k < config_.lights.size(); ++k)
      sky_irradiance += config_.ambient.dome_fraction * emitted[k] * config_.lights[k].irradiance;
    radiance += sky_response_ * sky_irradiance;
  }
  return radiance;
}

}  // namespace photorig::sim
