#pragma once
// The simulated rig's physical state: what object sits under the camera, where
// the LEDs are, how bright each one is right now. The simulated devices share
// one World, so a camera frame always shows the lights the controller set.

#include "photorig/sim/camera_model.h"
#include "photorig/sim/faults.h"
#include "photorig/sim/renderer.h"
#include "photorig/sim/scene.h"
#include "photorig/sim/sensor.h"

#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

namespace photorig::sim {

struct WorldConfig {
  Scene scene;
  std::vector<Light> lights;  // one per controller channel
  CameraModel camera;
  SensorModel sensor;
  std::uint64_t seed = 1;
  CameraFaults camera_faults;
  LightFaults light_faults;
};

class World {
 public:
  // Throws std::invalid_argument for an invalid scene or camera, and
  // std::runtime_error when a depth map or mesh cannot be read.
  explicit World(WorldConfig config);

  const WorldConfig& config() const { return config_; }
  const SurfaceMaps& surface() const { return surface_; }  // also the ground truth

  void SetLevels(std::vector<double> levels);
  std::vector<double> levels() const;
  // Radiance under the current light levels.
  cv::Mat RenderRadiance() const;

 private:
  WorldConfig config_;
  SurfaceMaps surface_;
  std::unique_ptr<Brdf> brdf_;
  bool cast_shadows_ = false;
  mutable std::mutex mutex_;
  std::vector<double> levels_;
};

}  // namespace photorig::sim
