// The lobe templates of lobes.h evaluated in double: models.h's Evaluate and EvaluateLobe.
#include "lobes.h"

#include <cmath>

namespace photorig::solvers::brdf {

Eigen::Vector3d Evaluate(const ModelParams& p, const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) {
  if (wi.z() <= 0.0 || wo.z() <= 0.0) return Eigen::Vector3d::Zero();
  return EvaluateAt(p, GeometryOf(wi, wo));
}

Eigen::Vector3d EvaluateAt(const ModelParams& p, const Geometry& g) {
  if (g.cos_i <= 0.0 || g.cos_o <= 0.0) return Eigen::Vector3d::Zero();
  Eigen::Vector3d f;
  const double factor = internal::LobeFactor(p.model, p.shape, internal::ExtraOf(p), g);
  for (int c = 0; c < 3; ++c) f[c] = p.diffuse[c] / M_PI + internal::ChannelLobe(p.model, p.specular[c], factor, g);
  if (HasSecondLobe(p.model)) {
    const double second = internal::BlinnPhongFactor(p.shape2, g);
    for (int c = 0; c < 3; ++c) f[c] += p.specular2[c] * second;
  }
  return f;
}

double EvaluateLobe(Model model, double specular, double shape, double extra, const Geometry& g) {
  if (g.cos_i <= 0.0 || g.cos_o <= 0.0) return 0.0;
  return internal::Lobe(model, specular, shape, extra, g);
}

}  // namespace photorig::solvers::brdf
