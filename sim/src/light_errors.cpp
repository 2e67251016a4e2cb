#include "photorig/sim/light_errors.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <random>

namespace photorig::sim {

void PerturbLights(const LightCalibrationError& error, std::uint64_t seed, std::vector<Light>* lights) {
  if (error.direction_rms_deg > 0.0) {
    std::mt19937_64 rng(seed ^ 0x5eedD1ec7ULL);
    std::normal_distribution<double> offset(0.0, error.direction_rms_deg * M_PI / 180.0 / std::sqrt(2.0));
    for (Light& light : *lights) {
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
  if (error.intensity_rms_pct > 0.0) {
    std::mt19937_64 rng(seed ^ 0x1e7e751caULL);
    std::normal_distribution<double> relative(0.0, error.intensity_rms_pct / 100.0);
    for (Light& light : *lights) light.irradiance *= std::max(0.01, 1.0 + relative(rng));
  }
}

}  // namespace photorig::sim
