#pragma once
// Radiance of a Lambertian scene under distant lights, seen orthographically.
//   L(p) = albedo(p) / pi * sum_k E_k * max(0, n(p) . w_k) * V_k(p)
// V_k is 1 unless the heightfield itself blocks the light (cast shadow).

#include "photorig/sim/scene.h"

#include <Eigen/Core>

#include <vector>

namespace photorig::sim {

struct DirectionalLight {
  Eigen::Vector3d direction{0.0, 0.0, 1.0};  // unit, towards the light
  double irradiance = 1.0;                   // at the object, for drive level 1
};

// `levels[k]` scales light k (0 = off). Threads over rows; the result does not
// depend on the thread count.
cv::Mat RenderRadiance(const SurfaceMaps& surface, bool cast_shadows,
                       const std::vector<DirectionalLight>& lights, const std::vector<double>& levels);

// 1 where the heightfield blocks the light towards `direction`, found by
// marching from each pixel towards the light until the ray clears the highest
// point of the surface.
cv::Mat CastShadowMask(const SurfaceMaps& surface, const Eigen::Vector3d& direction);

}  // namespace photorig::sim
