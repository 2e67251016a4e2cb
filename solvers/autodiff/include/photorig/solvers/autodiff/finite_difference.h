// Finite-difference Jacobians, the reference that needs nothing but double evaluations.
//
// Step choice. With h the step, eps = 2^-52 and f, f'', f''' of comparable scale:
//   forward   (f(x+h) - f(x)) / h:        error ~ h |f''| / 2  + 2 eps |f| / h,
//             minimised at h ~ sqrt(eps) ~ 1.5e-8, leaving an error ~ sqrt(eps);
//   central   (f(x+h) - f(x-h)) / (2h):   error ~ h^2 |f'''| / 6 + eps |f| / h,
//             minimised at h ~ cbrt(eps) ~ 6.1e-6, leaving an error ~ eps^(2/3) ~ 4e-11.
// The first term is truncation (shrinks with h), the second is rounding in f's values amplified
// by 1/h (grows as h shrinks): the V of docs/charts/autodiff_fd_accuracy.png. The step is scaled
// by max(1, |x|): relative for large inputs (so that x + h differs from x by far more than one
// rounding), absolute near 0 (where a relative step would vanish). Finally h is rounded so that
// x + h is exactly representable, removing the error of the step itself.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "photorig/solvers/autodiff/function.h"

namespace photorig::solvers::autodiff {

enum class DifferenceScheme { kForward, kCentral };

struct FiniteDifferenceOptions {
  DifferenceScheme scheme = DifferenceScheme::kCentral;
  // The step for input j is relative_step * max(1, |x_j|); 0 selects DefaultRelativeStep(scheme).
  double relative_step = 0.0;
  bool IsValid(std::string* why) const {
    if (!(relative_step >= 0.0 && relative_step < 1.0)) {
      if (why) *why = "relative_step must be in [0, 1) (0: the scheme's default)";
      return false;
    }
    return true;
  }
};

// sqrt(eps) for forward differences, cbrt(eps) for central ones (see the top of this file).
inline double DefaultRelativeStep(DifferenceScheme scheme) {
  constexpr double kEpsilon = std::numeric_limits<double>::epsilon();
  return scheme == DifferenceScheme::kForward ? std::sqrt(kEpsilon) : std::cbrt(kEpsilon);
}

// Value and Jacobian by finite differences: num_inputs + 1 evaluations (forward) or
// 2 num_inputs + 1 (central). Returns false, leaving the outputs unspecified, if the options are
// invalid or any evaluation fails (for instance a step that crosses into an invalid region). An
// evaluation, not a solve: it reports with a bool like the functions it differentiates.
template <DifferentiableFunction F>
bool FiniteDifferenceJacobian(const F& f, const double* x, const FiniteDifferenceOptions& options,
                              Eigen::VectorXd* value, Eigen::MatrixXd* jacobian) {
  if (!options.IsValid(nullptr)) return false;
  const int num_inputs = f.num_inputs();
  const int num_outputs = f.num_outputs();
  const double relative_step =
      options.relative_step > 0.0 ? options.relative_step : DefaultRelativeStep(options.scheme);
  std::vector<double> shifted(x, x + num_inputs);
  Eigen::VectorXd plus(num_outputs);
  Eigen::VectorXd minus(num_outputs);
  value->resize(num_outputs);
  jacobian->resize(num_outputs, num_inputs);
  if (!f(x, value->data())) {
    return false;
  }
  for (int j = 0; j < num_inputs; ++j) {
    const double h = relative_step * std::max(1.0, std::abs(x[j]));
    shifted[j] = x[j] + h;
    const double step_up = shifted[j] - x[j];  // Exactly representable.
    if (!f(shifted.data(), plus.data())) {
      return false;
    }
    if (options.scheme == DifferenceScheme::kForward) {
      for (int i = 0; i < num_outputs; ++i) {
        (*jacobian)(i, j) = (plus[i] - (*value)[i]) / step_up;
      }
    } else {
      shifted[j] = x[j] - h;
      const double step_down = x[j] - shifted[j];
      if (!f(shifted.data(), minus.data())) {
        return false;
      }
      for (int i = 0; i < num_outputs; ++i) {
        (*jacobian)(i, j) = (plus[i] - minus[i]) / (step_up + step_down);
      }
    }
    shifted[j] = x[j];
  }
  return true;
}

}  // namespace photorig::solvers::autodiff
