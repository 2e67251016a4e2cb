// Hand-derived derivatives of the Blinn-Phong rendering (blinn_phong.h): the reference the
// automatic methods are checked against, and the fastest method when the model is fixed.
//
// For one light, with c = w_i . n > 0, h = max(0, w_h . n), k = (e + 2) / (2 pi):
//   I         = L (rho_d / pi + rho_s k h^e) c
//   dI/dn     = L ( rho_s k (e h^(e-1) c w_h + h^e w_i) + rho_d / pi w_i )
//   dI/drho_d = L c / pi
//   dI/drho_s = L c k h^e
//   dI/de     = L c rho_s ( h^e / (2 pi) + k h^e ln h )
// Summing dI/dn over lights gives the pixel gradient dL_o/dn. At c <= 0 every derivative is 0;
// at h = 0 the terms through h vanish (the zero subgradient of the clamp, and h^e ln h -> 0).
#pragma once

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Core>

#include "photorig/solvers/autodiff/blinn_phong.h"
#include "photorig/solvers/autodiff/vector.h"

namespace photorig::solvers::autodiff {

// One light's intensity and its gradient w.r.t. the unit normal and the material.
struct BlinnPhongLightGradient {
  double intensity = 0.0;
  Eigen::Vector3d d_normal = Eigen::Vector3d::Zero();
  double d_diffuse_albedo = 0.0;
  double d_specular_albedo = 0.0;
  double d_exponent = 0.0;
};

inline BlinnPhongLightGradient SymbolicBlinnPhongLightGradient(
    const Eigen::Vector3d& normal, double diffuse_albedo, double specular_albedo, double exponent,
    const Eigen::Vector3d& light_direction, const Eigen::Vector3d& half_vector,
    double light_intensity) {
  constexpr double kInvPi = std::numbers::inv_pi;
  BlinnPhongLightGradient gradient;
  const double c = light_direction.dot(normal);
  if (c <= 0.0) {
    return gradient;
  }
  const double h = std::max(0.0, half_vector.dot(normal));
  const double k = (exponent + 2.0) * 0.5 * kInvPi;
  const double lobe = std::pow(h, exponent);
  // e h^(e-1) as e h^e / h: one pow per light instead of two.
  const double d_lobe_d_h = h > 0.0 ? exponent * lobe / h : 0.0;
  const double d_lobe_d_exponent = h > 0.0 ? lobe * std::log(h) : 0.0;
  const double brdf = diffuse_albedo * kInvPi + specular_albedo * k * lobe;

  gradient.intensity = light_intensity * brdf * c;
  gradient.d_normal =
      light_intensity *
      (specular_albedo * k * (d_lobe_d_h * c * half_vector + lobe * light_direction) +
       diffuse_albedo * kInvPi * light_direction);
  gradient.d_diffuse_albedo = light_intensity * c * kInvPi;
  gradient.d_specular_albedo = light_intensity * c * k * lobe;
  gradient.d_exponent =
      light_intensity * c * specular_albedo * (lobe * 0.5 * kInvPi + k * d_lobe_d_exponent);
  return gradient;
}

// Residuals and N x 6 Jacobian of BlinnPhongPixel from the formulas above, chained through the
// normalisation n = m / |m|: dn/dm = (I - n n^T) / |m|. False if the normal is degenerate.
inline bool SymbolicBlinnPhongJacobian(const BlinnPhongPixel& pixel, const double* parameters,
                                       Eigen::VectorXd* residuals, Eigen::MatrixXd* jacobian) {
  const Eigen::Vector3d m(parameters[BlinnPhongPixel::kNormal],
                          parameters[BlinnPhongPixel::kNormal + 1],
                          parameters[BlinnPhongPixel::kNormal + 2]);
  const NormalizeResult<double, 3> normal = NormalizeGuarded(m);
  if (!normal.valid) {
    return false;
  }
  const Eigen::Vector3d& n = normal.direction;
  const Eigen::Matrix3d d_normal_d_m = (Eigen::Matrix3d::Identity() - n * n.transpose()) / m.norm();

  const int num_lights = pixel.num_lights();
  residuals->resize(num_lights);
  jacobian->resize(num_lights, BlinnPhongPixel::kNumParameters);
  for (int i = 0; i < num_lights; ++i) {
    const BlinnPhongLightGradient g = SymbolicBlinnPhongLightGradient(
        n, parameters[BlinnPhongPixel::kDiffuseAlbedo],
        parameters[BlinnPhongPixel::kSpecularAlbedo], parameters[BlinnPhongPixel::kExponent],
        pixel.light_direction(i), pixel.half_vector(i), pixel.light_intensity(i));
    (*residuals)[i] = g.intensity - pixel.observed_intensity(i);
    // d_normal_d_m is symmetric, so row i is (d_normal_d_m * dI/dn)^T.
    jacobian->block<1, 3>(i, BlinnPhongPixel::kNormal) = (d_normal_d_m * g.d_normal).transpose();
    (*jacobian)(i, BlinnPhongPixel::kDiffuseAlbedo) = g.d_diffuse_albedo;
    (*jacobian)(i, BlinnPhongPixel::kSpecularAlbedo) = g.d_specular_albedo;
    (*jacobian)(i, BlinnPhongPixel::kExponent) = g.d_exponent;
  }
  return true;
}

}  // namespace photorig::solvers::autodiff
