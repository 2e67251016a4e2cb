#pragma once
// One measured BRDF value: the configuration and what was measured there.

#include <Eigen/Core>

namespace photorig::solvers::brdf {

struct BrdfSample {
  Eigen::Vector3d wi = Eigen::Vector3d::UnitZ();  // towards the light, sample frame (normal = z), unit
  Eigen::Vector3d wo = Eigen::Vector3d::UnitZ();  // towards the camera, unit
  // f_r in 1/sr per channel (R, G, B): the BRDF itself, not the cosine-weighted
  // reflected radiance L / E = f_r cos theta_i.
  Eigen::Vector3d value = Eigen::Vector3d::Zero();
  // Standard deviation of `value` per channel, 1/sr; 0 when not known.
  Eigen::Vector3d sigma = Eigen::Vector3d::Zero();
};

}  // namespace photorig::solvers::brdf
