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
class GgxPixel : public OneLobeParameters {
 public:
  static constexpr int kRoughness = kLobeShape;

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
  double light_intensity(int i) const { return lights_.light_intensity(i); }
  double observed_intensity(int i) const { return lights_.observed_intensity(i); }
  const Eigen::Vector3d& view_direction() const { return view_; }

 private:
  BlinnPhongPixel lights_;  // the lights, half vectors and observations (its lobe is not used)
  Eigen::Vector3d view_;
};

// G1 at c = w . n with its derivatives in c and in a^2. With r = sqrt(a^2 + (1 - a^2) c^2):
// dG1/dc = 2 a^2 / (r (c + r)^2) and dG1/d(a^2) = -c (1 - c^2) / (r (c + r)^2).
struct GgxShadowing {
  double value, d_cos, d_a2;
};
inline GgxShadowing GgxG1(double cos_angle, double a2) {
  const double r = std::sqrt(a2 + (1.0 - a2) * cos_angle * cos_angle), sum = cos_angle + r;
  const double q = 1.0 / (r * sum * sum);
  return {2.0 * cos_angle / sum, 2.0 * a2 * q, -cos_angle * (1.0 - cos_angle * cos_angle) * q};
}

// Residuals and N x 6 Jacobian of GgxPixel from hand-derived formulas (forward mode carries six
// tangents through every operation: 5.7x a residual evaluation against 3.5x here, bench_autodiff), chained through
// n = m / |m| as SymbolicBlinnPhongJacobian. The lobe term is rho_s S(n) G1(w . n) / t^2 with
// the per-pixel S = a^2 G1(v . n) / (4 pi v . n) and t = (h . n)^2 (a^2 - 1) + 1.
// False if the normal is degenerate.
inline bool SymbolicGgxJacobian(const GgxPixel& pixel, const double* parameters, Eigen::VectorXd* residuals,
                                Eigen::MatrixXd* jacobian) {
  constexpr double kInvPi = std::numbers::inv_pi;
  const Eigen::Vector3d m(parameters[GgxPixel::kNormal], parameters[GgxPixel::kNormal + 1],
                          parameters[GgxPixel::kNormal + 2]);
  const NormalizeResult<double, 3> normal = NormalizeGuarded(m);
  if (!normal.valid) return false;
  const Eigen::Vector3d& n = normal.direction;
  const Eigen::Matrix3d d_normal_d_m = (Eigen::Matrix3d::Identity() - n * n.transpose()) / m.norm();
  const double rho_d = parameters[GgxPixel::kDiffuseAlbedo], rho_s = parameters[GgxPixel::kSpecularAlbedo];
  const double a = parameters[GgxPixel::kRoughness], a2 = a * a;
  const Eigen::Vector3d& view = pixel.view_direction();
  const double cos_view = view.dot(n);
  // A normal facing away from the camera shows no lobe (as Predict).
  const bool lobe = cos_view > 0.0;
  // S per unit rho_s, with its derivatives in v . n and in a^2.
  double s = 0.0, ds_d_cos_view = 0.0, ds_d_a2 = 0.0;
  if (lobe) {
    const GgxShadowing g = GgxG1(cos_view, a2);
    const double k = 0.25 * kInvPi / cos_view;
    s = k * a2 * g.value;
    ds_d_cos_view = k * a2 * (g.d_cos - g.value / cos_view);
    ds_d_a2 = k * (g.value + a2 * g.d_a2);
  }
  const int num_lights = pixel.num_lights();
  residuals->resize(num_lights);
  jacobian->setZero(num_lights, GgxPixel::kNumParameters);
  for (int i = 0; i < num_lights; ++i) {
    const Eigen::Vector3d w = pixel.light_direction(i);
    const double cos_light = w.dot(n), intensity = pixel.light_intensity(i);
    if (cos_light <= 0.0) {
      (*residuals)[i] = -pixel.observed_intensity(i);
      continue;
    }
    double value = rho_d * kInvPi * cos_light, d_specular = 0.0, d_a2 = 0.0;
    Eigen::Vector3d d_normal = rho_d * kInvPi * w;
    if (lobe) {
      const Eigen::Vector3d h = pixel.half_vector(i);
      const double cos_half = std::max(0.0, h.dot(n));
      const double t = cos_half * cos_half * (a2 - 1.0) + 1.0, inv_t2 = 1.0 / (t * t);
      const GgxShadowing g = GgxG1(cos_light, a2);
      d_specular = s * g.value * inv_t2;  // the lobe per unit rho_s
      value += rho_s * d_specular;
      // d(1/t^2) = -2 / t^3 dt, dt/dn = 2 (h . n)(a^2 - 1) h, dt/d(a^2) = (h . n)^2.
      const double d_inv_t2_d_t = -2.0 * inv_t2 / t;
      d_normal += rho_s * (ds_d_cos_view * g.value * inv_t2 * view + s * g.d_cos * inv_t2 * w +
                           s * g.value * d_inv_t2_d_t * 2.0 * cos_half * (a2 - 1.0) * h);
      d_a2 = rho_s * (ds_d_a2 * g.value * inv_t2 + s * g.d_a2 * inv_t2 + s * g.value * d_inv_t2_d_t * cos_half * cos_half);
    }
    (*residuals)[i] = intensity * value - pixel.observed_intensity(i);
    // d_normal_d_m is symmetric, so row i is (d_normal_d_m * dI/dn)^T.
    jacobian->block<1, 3>(i, GgxPixel::kNormal) = intensity * (d_normal_d_m * d_normal).transpose();
    (*jacobian)(i, GgxPixel::kDiffuseAlbedo) = intensity * cos_light * kInvPi;
    (*jacobian)(i, GgxPixel::kSpecularAlbedo) = intensity * d_specular;
    (*jacobian)(i, GgxPixel::kRoughness) = intensity * d_a2 * 2.0 * a;
  }
  return true;
}

// Residuals and Jacobian (N x 6) of a GgxPixel by `method`, as BlinnPhongResidualsAndJacobian.
inline bool GgxResidualsAndJacobian(const GgxPixel& pixel, const double* parameters, DerivativeMethod method,
                                    Eigen::VectorXd* residuals, Eigen::MatrixXd* jacobian, Tape* tape = nullptr) {
  switch (method) {
    case DerivativeMethod::kForward:
      return ForwardJacobian<GgxPixel::kNumParameters>(pixel, parameters, residuals, jacobian);
    case DerivativeMethod::kSymbolic:
      return SymbolicGgxJacobian(pixel, parameters, residuals, jacobian);
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
