#include "model_selection.h"

#include <cmath>

namespace photorig::ps::internal {
namespace {

double InverseNormalCdf(double p) {
  // Bisection on the CDF: called once per solve, so speed is irrelevant.
  double lo = -10.0, hi = 10.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (0.5 * std::erfc(-mid / std::sqrt(2.0)) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace

std::vector<double> ChiSquareQuantiles(int max_dof, double p) {
  const double z = InverseNormalCdf(p);
  std::vector<double> quantile(max_dof + 1, 0.0);
  for (int dof = 1; dof <= max_dof; ++dof) {
    const double v = dof, t = 1.0 - 2.0 / (9.0 * v) + z * std::sqrt(2.0 / (9.0 * v));
    quantile[dof] = v * t * t * t;
  }
  return quantile;
}

}  // namespace photorig::ps::internal
