// GGX (Trowbridge-Reitz) rendering of one pixel under N directional lights, written once for
// every scalar type (double, Dual, Var), beside BlinnPhongPixel:
//
//   I_i = L_i (rho_d / pi max(0, w_i . n) + rho_s D(w_h) G1(w_i) G1(w_o) / (4 (w_o . n))),
//   D(h)  = a^2 / (pi ((h . n)^2 (a^2 - 1) + 1)^2),
//   G1(w) = 2 (w . n) / ((w . n) + sqrt(a^2 + (1 - a^2) (w . n)^2))   (separable Smith),
//
// the microfacet lobe D F G1 G1 / (4 (w_i . n)(w_o . n)) times the cosine, with the Fresnel
// factor F folded into rho_s. Under one view direction F(w_i . w_h) depends on the light alone,
// and for lights within 90 deg of the view w_i . w_h >= cos 45 deg, where Schlick's
// (1 - w_i . w_h)^5 is below 0.0022: F is constant to 0.3 % of F0 over any dome, so a
// photometric-stereo stack can tell rho_s F0 apart from neither factor alone.
#pragma once

#include <cmath>
#include <numbers>

#include <Eigen/Core>

#include "photorig/solvers/autodiff/blinn_phong.h"
#include "photorig/solvers/autodiff/blinn_phong_jacobian.h"
#include "photorig/solvers/autodiff/finite_difference.h"
#include "photorig/solvers/autodiff/jacobian.h"
#include "photorig/solvers/autodiff/tape.h"
#include "photorig/solvers/autodiff/vector.h"

namespace photorig::solvers::autodiff {

// Residual functor of one pixel for a photometric-stereo fit with a GGX lobe:
// residual_i = I_i - observed_i. Parameters (kNumParameters = 6): the normal as 3 unconstrained
// components normalised inside (as BlinnPhongPixel, for the same reason), rho_d, rho_s, a.
// Lights, half vectors and intensities as BlinnPhongPixel's, which holds them.
class GgxPixel {
 public:
  static constexpr int kNormal = 0;  // 3 components
  static constexpr int kDiffuseAlbedo = 3;
  static constexpr int kSpecularAlbedo = 4;
  static constexpr int kRoughness = 5;
  static constexpr int kNumParameters = 6;

  GgxPixel(const Eigen::Matrix<double, Eigen::Dynamic, 3>& light_directions, Eigen::VectorXd light_intensities,
           const Eigen::Vector3d& view_direction, Eigen::VectorXd observed_intensities)
      : lights_(light_directions, std::move(light_intensities), view_direction, std::move(observed_intensities)),
        view_(view_direction.normalized()) {}

  int num_lights() const { return lights_.num_lights(); }
  int num_inputs() const { return kNumParameters; }
  int num_outputs() const { return num_lights(); }

  template <typename T>
  bool operator()(const T* parameters, T* residuals) const {
    if (!Predict(parameters, residuals)) return false;
    for (int i = 0; i < num_lights(); ++i) residuals[i] -= lights_.observed_intensity(i);
    return true;
  }

  // Predicted intensities; false if the normal is degenerate.
  template <typename T>
  bool Predict(const T* parameters, T* intensities) const {
    using std::max;
    using std::sqrt;
    const Eigen::Matrix<T, 3, 1> m(parameters[kNormal], parameters[kNormal + 1], parameters[kNormal + 2]);
    const NormalizeResult<T, 3> normal = NormalizeGuarded(m);
    if (!normal.valid) return false;
    const T diffuse = parameters[kDiffuseAlbedo] * std::numbers::inv_pi;
    const T a2 = parameters[kRoughness] * parameters[kRoughness];
    const T cos_view = Dot(view_, normal.direction);
    // A normal facing away from the camera shows no lobe (and its pixel is not seen).
    const bool lobe = cos_view > 0.0;
    auto g1 = [&a2](const T& c) { return 2.0 * c / (c + sqrt(a2 + (1.0 - a2) * c * c)); };
    // The per-pixel factors: rho_s a^2 G1(w_o) / (4 pi (w_o . n)).
    const T specular = lobe ? T(parameters[kSpecularAlbedo] * a2 * g1(cos_view) * (0.25 * std::numbers::inv_pi) /
                                cos_view)
                            : T(0.0);
    for (int i = 0; i < num_lights(); ++i) {
      const T cos_light = Dot(lights_.light_direction(i), normal.direction);
      if (cos_light <= 0.0) {
        intensities[i] = T(0.0);
        continue;
      }
      T value = diffuse * cos_light;
      if (lobe) {
        const T cos_half = max(T(0.0), Dot(lights_.half_vector(i), normal.direction));
        const T t = cos_half * cos_half * (a2 - 1.0) + 1.0;
        value = value + specular * g1(cos_light) / (t * t);
      }
      intensities[i] = lights_.light_intensity(i) * value;
    }
    return true;
  }

  Eigen::Vector3d light_direction(int i) const { return lights_.light_direction(i); }
  Eigen::Vector3d half_vector(int i) const { return lights_.half_vector(i); }

 private:
  BlinnPhongPixel lights_;  // the lights, half vectors and observations (its lobe is not used)
  Eigen::Vector3d view_;
};

// Residuals and Jacobian (N x 6) of a GgxPixel by `method`, as BlinnPhongResidualsAndJacobian.
// No hand-derived formulas: kSymbolic takes forward mode.
inline bool GgxResidualsAndJacobian(const GgxPixel& pixel, const double* parameters, DerivativeMethod method,
                                    Eigen::VectorXd* residuals, Eigen::MatrixXd* jacobian, Tape* tape = nullptr) {
  switch (method) {
    case DerivativeMethod::kForward:
    case DerivativeMethod::kSymbolic:
      return ForwardJacobian<GgxPixel::kNumParameters>(pixel, parameters, residuals, jacobian);
    case DerivativeMethod::kReverse: {
      if (tape != nullptr) return ReverseJacobian(pixel, parameters, tape, residuals, jacobian);
      Tape local_tape;
      return ReverseJacobian(pixel, parameters, &local_tape, residuals, jacobian);
    }
    case DerivativeMethod::kCentralDifference:
      return FiniteDifferenceJacobian(pixel, parameters, FiniteDifferenceOptions{.scheme = DifferenceScheme::kCentral},
                                      residuals, jacobian);
  }
  return false;
}

}  // namespace photorig::solvers::autodiff
