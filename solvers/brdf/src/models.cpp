#include "photorig/solvers/brdf/models.h"

#include "lobes.h"

#include <algorithm>
#include <cmath>

namespace photorig::solvers::brdf {

const char* ModelName(Model model) {
  switch (model) {
    case Model::kLambertian: return "lambertian";
    case Model::kBlinnPhong: return "blinn_phong";
    case Model::kWard: return "ward";
    case Model::kGgx: return "ggx";
    case Model::kCookTorrance: return "cook_torrance";
    case Model::kTwoBlinnPhong: return "two_blinn_phong";
  }
  return "?";
}

std::optional<Model> ParseModel(std::string_view name) {
  for (Model m : {Model::kLambertian, Model::kBlinnPhong, Model::kWard, Model::kGgx, Model::kCookTorrance,
                  Model::kTwoBlinnPhong})
    if (name == ModelName(m)) return m;
  return std::nullopt;
}

int ParameterCount(Model model) {
  if (model == Model::kLambertian) return 3;
  if (model == Model::kTwoBlinnPhong) return 11;
  return model == Model::kCookTorrance || model == Model::kGgx ? 8 : 7;
}

bool HasSecondLobe(Model model) { return model == Model::kTwoBlinnPhong; }

Geometry GeometryOf(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) {
  const Eigen::Vector3d h = (wi + wo).normalized();
  return {wi.z(), wo.z(), h.z(), wi.dot(h)};
}

Eigen::Vector3d Evaluate(const ModelParams& p, const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) {
  if (wi.z() <= 0.0 || wo.z() <= 0.0) return Eigen::Vector3d::Zero();
  const Geometry g = GeometryOf(wi, wo);
  Eigen::Vector3d f;
  for (int c = 0; c < 3; ++c) f[c] = p.diffuse[c] / M_PI + internal::Lobe(p.model, p.specular[c], p.shape, internal::ExtraOf(p), g);
  if (HasSecondLobe(p.model))
    for (int c = 0; c < 3; ++c) f[c] += internal::BlinnPhongLobe(p.specular2[c], p.shape2, g);
  return f;
}

double EvaluateLobe(Model model, double specular, double shape, double extra, const Geometry& g) {
  if (g.cos_i <= 0.0 || g.cos_o <= 0.0) return 0.0;
  return internal::Lobe(model, specular, shape, extra, g);
}

Eigen::Vector3d DirectionalAlbedo(const ModelParams& params, const Eigen::Vector3d& wi, int theta_steps) {
  // Cells of equal solid angle: uniform in cos theta_o and phi_o.
  const int phi_steps = 4 * theta_steps;
  const double cell_sr = (1.0 / theta_steps) * (2.0 * M_PI / phi_steps);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (int i = 0; i < theta_steps; ++i) {
    const double cos_o = (i + 0.5) / theta_steps, sin_o = std::sqrt(1.0 - cos_o * cos_o);
    for (int j = 0; j < phi_steps; ++j) {
      const double phi = (j + 0.5) * 2.0 * M_PI / phi_steps;
      const Eigen::Vector3d wo(sin_o * std::cos(phi), sin_o * std::sin(phi), cos_o);
      sum += Evaluate(params, wi, wo) * cos_o;
    }
  }
  return sum * cell_sr;
}

}  // namespace photorig::solvers::brdf
