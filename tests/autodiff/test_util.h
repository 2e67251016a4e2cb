// Shared fixtures of the autodiff tests: a vector function exercising every elementary operation,
// and Jacobian comparison with a per-column relative tolerance.
#pragma once

#include <algorithm>

#include <Eigen/Core>
#include <gtest/gtest.h>

namespace photorig::solvers::autodiff::testing {

// Two inputs (x > 0, y), four outputs, smooth near the points the tests use (x in [0.5, 2],
// y in [-1, 1] away from the kinks of abs, max, min, clamp at y = 0.3, x = y, y = 0.1, 0.9).
struct AllOperations {
  int num_inputs() const { return 2; }
  int num_outputs() const { return 4; }

  template <typename T>
  bool operator()(const T* in, T* out) const {
    using std::abs, std::atan2, std::cos, std::exp, std::log, std::max, std::min, std::pow,
        std::sin, std::sqrt, std::clamp;
    const T& x = in[0];
    const T& y = in[1];
    out[0] = sin(x) * exp(y) / sqrt(x) + log(x) * cos(y);
    out[1] = pow(x, y) + pow(x, 2.5) + pow(2.0, y);
    out[2] = atan2(y, x) * abs(y - 0.3) + max(x, y) - min(x, y) * clamp(y, T(0.1), T(0.9));
    out[3] = (x * x - 3.0 * y) / (1.0 + x * y) + 2.0 / x - (y - 1.0) * 0.5;
    T accumulated(1.0);
    accumulated += x;
    accumulated -= y;
    accumulated *= x;
    accumulated /= (2.0 + y * y);
    out[3] += -accumulated;
    return true;
  }
};

// max over columns j of max_i |a_ij - b_ij| / max_i |b_ij|: the error of each derivative relative
// to the scale of that derivative across outputs. Columns of b that are all zero count absolute.
inline double ColumnRelativeError(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  EXPECT_EQ(a.rows(), b.rows());
  EXPECT_EQ(a.cols(), b.cols());
  double worst = 0.0;
  for (Eigen::Index j = 0; j < b.cols(); ++j) {
    const double scale = b.col(j).cwiseAbs().maxCoeff();
    const double error = (a.col(j) - b.col(j)).cwiseAbs().maxCoeff();
    worst = std::max(worst, scale > 0.0 ? error / scale : error);
  }
  return worst;
}

}  // namespace photorig::solvers::autodiff::testing
