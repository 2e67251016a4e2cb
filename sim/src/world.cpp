#include "photorig/sim/world.h"

namespace photorig::sim {

World::World(WorldConfig config)
    : config_(std::move(config)),
      surface_(SampleSurface(config_.scene, config_.camera.width, config_.camera.height,
                             config_.camera.pixel_pitch_mm)),
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
  const bool cast_shadows = config_.scene.cast_shadows && config_.scene.shape == Scene::Shape::kBumps;
  return sim::RenderRadiance(surface_, cast_shadows, config_.lights, levels());
}

}  // namespace photorig::sim
