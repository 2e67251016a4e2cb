#include "photorig/solvers/brdf/models.h"

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
