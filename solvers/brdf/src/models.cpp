#include "photorig/solvers/brdf/models.h"

#include "photorig/solvers/core/names.h"

#include <algorithm>
#include <cmath>

namespace photorig::solvers::brdf {

namespace {

constexpr core::NameTable<Model, 6> kModelNames = {{
    {Model::kLambertian, "lambertian"}, {Model::kBlinnPhong, "blinn_phong"}, {Model::kWard, "ward"},
    {Model::kGgx, "ggx"}, {Model::kCookTorrance, "cook_torrance"}, {Model::kTwoBlinnPhong, "two_blinn_phong"},
}};

}  // namespace

const char* ModelName(Model model) { return core::NameOf(kModelNames, model); }

std::optional<Model> ParseModel(std::string_view name) { return core::ParseName(kModelNames, name); }

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

Eigen::Vector3d NormalAlbedo(const ModelParams& params, int theta_h_steps) {
  // theta_h = (pi/4) u^2 over u in (0, 1): w_o from the normal to the horizon.
  const Eigen::Vector3d wi = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (int k = 0; k < theta_h_steps; ++k) {
    const double u = (k + 0.5) / theta_h_steps, theta_h = 0.25 * M_PI * u * u;
    const double d_theta_h = 0.5 * M_PI * u / theta_h_steps;
    const Eigen::Vector3d wo(std::sin(2.0 * theta_h), 0.0, std::cos(2.0 * theta_h));
    // f cos theta_o d omega_o, d omega_o = 4 cos theta_h sin theta_h d theta_h d phi_h, phi_h over 2 pi.
    sum += Evaluate(params, wi, wo) * (wo.z() * 4.0 * std::cos(theta_h) * std::sin(theta_h) * 2.0 * M_PI * d_theta_h);
  }
  return sum;
}

}  // namespace photorig::solvers::brdf
