// Vector helpers written once for every scalar type (double, Dual, Var, ceres::Jet).
//
// Normalising a vector that may be (close to) zero: v / |v| has derivative
// (I - v v^T / |v|^2) / |v|, which grows without bound as |v| -> 0 and is undefined at 0. Plain
// Eigen normalized() on a Dual or Var vector returns the input unchanged when the squared norm
// is exactly 0 (and underflows to that case below |v| ~ 1e-154), silently handing back a
// non-unit "direction". NormalizeGuarded() instead reports the degenerate case.
#pragma once

#include <cmath>

#include <Eigen/Core>

namespace photorig::solvers::autodiff {

// Below this norm a direction is treated as undefined. Inputs of order 1 carry rounding errors
// of order 1e-16, so at |v| = 1e-8 the direction is still good to ~1e-8 while its derivative
// (~1/|v|) is already 1e8 times the scale of the inputs: smaller vectors are almost surely the
// product of cancellation, not a meaningful direction.
inline constexpr double kDefaultMinNorm = 1e-8;

template <typename T, int Rows>
struct NormalizeResult {
  // v / |v| when valid; the zero vector, with all derivatives zero, otherwise.
  Eigen::Matrix<T, Rows, 1> direction;
  bool valid;
};

// Works for double, Dual, Var and ceres::Jet: it only needs comparisons, sqrt and arithmetic.
template <typename T, int Rows>
NormalizeResult<T, Rows> NormalizeGuarded(const Eigen::Matrix<T, Rows, 1>& v,
                                          double min_norm = kDefaultMinNorm) {
  using std::sqrt;
  const T squared_norm = v.squaredNorm();
  // Written so that a NaN norm also lands in the invalid branch.
  if (!(squared_norm >= T(min_norm * min_norm))) {
    return {Eigen::Matrix<T, Rows, 1>::Zero(v.size()), false};
  }
  const T inverse_norm = 1.0 / sqrt(squared_norm);
  return {v * inverse_norm, true};
}

// w . v for a constant w. Var has an overload in tape.h that records two fused nodes instead of
// the five of the generic expression; found by argument-dependent lookup.
template <typename T>
T Dot(const Eigen::Vector3d& w, const Eigen::Matrix<T, 3, 1>& v) {
  return w.dot(v);
}

}  // namespace photorig::solvers::autodiff
