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
  return config;
}

}  // namespace

World::World(WorldConfig config)
    : config_(Validated(config)),
      surface_(SampleSurface(config_.scene, config_.camera)),
      brdf_(config_.scene.material.MakeBrdf(config_.scene.albedo.high)),
      // The sweep needs the heightfield on the pixel grid, i.e. an orthographic view.
      cast_shadows_(config_.scene.cast_shadows && config_.scene.IsHeightfield() && surface_.height_on_pixel_grid),
      levels_(config_.lights.size(), 0.0) {}

void World::SetLevels(std::vector<double> levels) {
  std::lock_guard lock(mutex_);
  levels_ = std::move(levels);
}

std::vector<double> World::levels() const {
  std::lock_guard lock(mutex_);
  return levels_;
}

cv::Mat World::RenderRadiance() const {
  // The backlight belongs to the scene, not to the dome: it is always on.
  if (config_.scene.shape == Scene::Shape::kVolume)
    return RenderTransmission(surface_.line_integrals, config_.scene.backlight_radiance);
  return sim::RenderRadiance(surface_, *brdf_, cast_shadows_, config_.lights, levels());
}

}  // namespace photorig::sim
