// One entry point for the Blinn-Phong fit: residuals and Jacobian of a BlinnPhongPixel by a
// derivative method chosen at run time.
#pragma once

#include <Eigen/Core>

#include "photorig/solvers/autodiff/blinn_phong.h"
#include "photorig/solvers/autodiff/blinn_phong_symbolic.h"
#include "photorig/solvers/autodiff/finite_difference.h"
#include "photorig/solvers/autodiff/jacobian.h"
#include "photorig/solvers/autodiff/tape.h"

namespace photorig::solvers::autodiff {

enum class DerivativeMethod {
  kForward,            // Dual<6>, one pass for all N lights: the default choice.
  kReverse,            // Tape, one sweep per light: O(N^2), for cross-checking.
  kSymbolic,           // Hand-derived formulas (blinn_phong_symbolic.h): as fast as kForward.
  kCentralDifference,  // 13 double evaluations, ~1e-9 relative error: the independent check.
};

inline const char* ToString(DerivativeMethod method) {
  switch (method) {
    case DerivativeMethod::kForward:
      return "forward";
    case DerivativeMethod::kReverse:
      return "reverse";
    case DerivativeMethod::kSymbolic:
      return "symbolic";
    case DerivativeMethod::kCentralDifference:
      return "central-difference";
  }
  return "unknown";
}

// Residuals (I_i - observed_i, N) and Jacobian (N x 6, parameter layout of BlinnPhongPixel) at
// `parameters`. `tape` is scratch memory for kReverse: pass one tape that lives across calls to
// avoid allocating; null allocates a fresh one. Returns false, leaving the outputs unspecified,
// when the normal is degenerate (for kCentralDifference: when a step makes it degenerate; for
// kReverse: also when the tape cannot record the residuals, Tape::ok()).
inline bool BlinnPhongResidualsAndJacobian(const BlinnPhongPixel& pixel, const double* parameters,
                                           DerivativeMethod method, Eigen::VectorXd* residuals,
                                           Eigen::MatrixXd* jacobian, Tape* tape = nullptr) {
  switch (method) {
    case DerivativeMethod::kForward:
      return ForwardJacobian<BlinnPhongPixel::kNumParameters>(pixel, parameters, residuals,
                                                              jacobian);
    case DerivativeMethod::kReverse: {
      if (tape != nullptr) {
        return ReverseJacobian(pixel, parameters, tape, residuals, jacobian);
      }
      Tape local_tape;
      return ReverseJacobian(pixel, parameters, &local_tape, residuals, jacobian);
    }
    case DerivativeMethod::kSymbolic:
      return SymbolicBlinnPhongJacobian(pixel, parameters, residuals, jacobian);
    case DerivativeMethod::kCentralDifference:
      return FiniteDifferenceJacobian(pixel, parameters,
                                      FiniteDifferenceOptions{.scheme = DifferenceScheme::kCentral},
                                      residuals, jacobian);
  }
  return false;
}

}  // namespace photorig::solvers::autodiff
