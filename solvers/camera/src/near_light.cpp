#include "photorig/solvers/camera/near_light.h"

#include <algorithm>

namespace photorig::solvers::camera {

NearLight NearLight::AtInfinity(const Eigen::Vector3d& direction) {
  const Eigen::Vector3d unit = direction.normalized();
  // Aimed at the origin with a Lambertian profile: every point is on its axis.
  return {.position_mm = unit, .axis = -unit, .cos_exponent = 1.0, .at_infinity = true};
}

PreparedNearLight::PreparedNearLight(const NearLight& light)
    : position_mm(light.position_mm), axis(light.axis), cos_exponent(light.cos_exponent), w(light.at_infinity ? 0.0 : 1.0) {
  const double origin_squared = position_mm.squaredNorm();
  const double origin_cos = std::max(1e-12, -axis.dot(position_mm) / std::sqrt(origin_squared));
  scale = origin_squared / std::pow(origin_cos, cos_exponent);
}

double NearLight::RelativeIrradiance(const Eigen::Vector3d& point_mm, Eigen::Vector3d* towards_light) const {
  return PreparedNearLight(*this).RelativeIrradiance(point_mm, towards_light);
}

}  // namespace photorig::solvers::camera
