// Blinn-Phong rendering of one pixel under N directional lights, written once for every scalar
// type (double, Dual, Var, ceres::Jet).
//
//   I_i = L_i f_r(w_i, w_o) max(0, w_i . n),
//   f_r = rho_d / pi + rho_s (e + 2) / (2 pi) max(0, w_h . n)^e,   w_h = (w_i + w_o) / |w_i + w_o|,
//
// with w_i the unit direction towards light i, w_o the unit direction towards the camera, L_i the
// light's intensity. The pixel radiance under all lights at once is L_o = sum_i I_i.
#pragma once

#include <cmath>
#include <numbers>
#include <utility>

#include <Eigen/Core>

#include "photorig/solvers/autodiff/vector.h"

namespace photorig::solvers::autodiff {

// The per-pixel factors of f_r, computed once and shared by all lights.
template <typename T>
struct BlinnPhongLobe {
  BlinnPhongLobe(const T& diffuse_albedo, const T& specular_albedo, const T& exponent)
      : diffuse(diffuse_albedo * std::numbers::inv_pi),
        specular(specular_albedo * (exponent + 2.0) * (0.5 * std::numbers::inv_pi)),
        exponent(exponent) {}

  T diffuse;   // rho_d / pi
  T specular;  // rho_s (e + 2) / (2 pi)
  T exponent;  // e
};

// f_r(w_i, w_o) max(0, w_i . n): the intensity per unit light intensity, for a unit normal.
template <typename T>
T BlinnPhongShading(const Eigen::Matrix<T, 3, 1>& normal, const BlinnPhongLobe<T>& lobe,
                    const Eigen::Vector3d& light_direction, const Eigen::Vector3d& half_vector) {
  using std::max;
  using std::pow;
  const T cos_light = Dot(light_direction, normal);
  // At or past grazing the light contributes nothing, value and derivative: at exactly
  // cos_light == 0 we take the zero subgradient (the one-sided derivative from the dark side).
  if (cos_light <= 0.0) {
    return T(0.0);
  }
  // max(0, .) returns the constant 0 on a tie (dual.h), so the lobe is flat at its clamp too.
  const T cos_half = max(T(0.0), Dot(half_vector, normal));
  return (lobe.diffuse + lobe.specular * pow(cos_half, lobe.exponent)) * cos_light;
}

// The parameters of a pixel with one specular lobe, BlinnPhongPixel's and GgxPixel's alike: the
// normal's 3 components, rho_d, rho_s, then the lobe's one shape parameter (Blinn-Phong's
// exponent, GGX's roughness). One layout, so that one fitter serves both lobes.
struct OneLobeParameters {
  static constexpr int kNormal = 0;  // 3 components
  static constexpr int kDiffuseAlbedo = 3;
  static constexpr int kSpecularAlbedo = 4;
  static constexpr int kLobeShape = 5;
  static constexpr int kNumParameters = 6;
};

// Residual functor of one pixel for a photometric-stereo fit: residual_i = I_i - observed_i.
//
// Parameters (kNumParameters = 6): the normal as 3 unconstrained components m, normalised
// inside (n = m / |m|), then rho_d, rho_s, e. Three components rather than two angles because
// angles put a singularity (a zero Jacobian column) at their pole, and a fronto-parallel normal
// is the most common one in photometric stereo; m has no singular direction except its length,
// along which every residual is constant. So the Jacobian's normal block has rank 2 (its rows
// are orthogonal to n): Levenberg-Marquardt damping handles that, and a fitter renormalises m
// after each step to keep its scale near 1. A normal shorter than kDefaultMinNorm makes
// evaluation fail (returns false) instead of producing NaN.
class BlinnPhongPixel : public OneLobeParameters {
 public:
  static constexpr int kExponent = kLobeShape;

  // light_directions: N x 3, rows towards each light (normalised here).
  // light_intensities, observed_intensities: N each; pass zeros as observed to render.
  // view_direction: towards the camera (normalised here).
  // A light exactly opposite the camera has no half vector; it gets none (w_h = 0), so it has
  // no specular highlight.
  BlinnPhongPixel(const Eigen::Matrix<double, Eigen::Dynamic, 3>& light_directions,
                  Eigen::VectorXd light_intensities, const Eigen::Vector3d& view_direction,
                  Eigen::VectorXd observed_intensities)
      : light_directions_(light_directions.transpose().colwise().normalized()),
        half_vectors_(3, light_directions.rows()),
        light_intensities_(std::move(light_intensities)),
        observed_intensities_(std::move(observed_intensities)) {
    const Eigen::Vector3d view = view_direction.normalized();
    for (int i = 0; i < num_lights(); ++i) {
      const Eigen::Vector3d sum = light_directions_.col(i) + view;
      half_vectors_.col(i) = NormalizeGuarded(sum).direction;
    }
  }

  int num_lights() const { return static_cast<int>(light_directions_.cols()); }
  int num_inputs() const { return kNumParameters; }
  int num_outputs() const { return num_lights(); }

  // Residuals I_i - observed_i; false if the normal is degenerate.
  template <typename T>
  bool operator()(const T* parameters, T* residuals) const {
    if (!Predict(parameters, residuals)) {
      return false;
    }
    for (int i = 0; i < num_lights(); ++i) {
      residuals[i] -= observed_intensities_[i];
    }
    return true;
  }

  // Predicted intensities I_i; false if the normal is degenerate.
  template <typename T>
  bool Predict(const T* parameters, T* intensities) const {
    const Eigen::Matrix<T, 3, 1> m(parameters[kNormal], parameters[kNormal + 1],
                                   parameters[kNormal + 2]);
    const NormalizeResult<T, 3> normal = NormalizeGuarded(m);
    if (!normal.valid) {
      return false;
    }
    const BlinnPhongLobe<T> lobe(parameters[kDiffuseAlbedo], parameters[kSpecularAlbedo],
                                 parameters[kExponent]);
    for (int i = 0; i < num_lights(); ++i) {
      intensities[i] = light_intensities_[i] * BlinnPhongShading<T>(normal.direction, lobe,
                                                                    light_directions_.col(i),
                                                                    half_vectors_.col(i));
    }
    return true;
  }

  Eigen::Vector3d light_direction(int i) const { return light_directions_.col(i); }
  Eigen::Vector3d half_vector(int i) const { return half_vectors_.col(i); }
  double light_intensity(int i) const { return light_intensities_[i]; }
  double observed_intensity(int i) const { return observed_intensities_[i]; }

 private:
  Eigen::Matrix3Xd light_directions_;  // Column i: w_i.
  Eigen::Matrix3Xd half_vectors_;      // Column i: w_h for light i.
  Eigen::VectorXd light_intensities_;
  Eigen::VectorXd observed_intensities_;
};

}  // namespace photorig::solvers::autodiff
