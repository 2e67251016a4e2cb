#pragma once
// The standard normal's quantile, for the solvers' statistical tests: the
// chi-square thresholds of photometric stereo's model ladder, the
// reflectance fit's test of whether two groups of pixels are one.

#include <cmath>

namespace photorig::solvers::core {

// The z with Phi(z) = p, by bisection on the CDF: called a few times a solve,
// so speed is irrelevant, and 200 halvings of [-40, 40] end at adjacent doubles.
inline double NormalQuantile(double p) {
  double lo = -40.0, hi = 40.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (0.5 * std::erfc(-mid / std::sqrt(2.0)) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace photorig::solvers::core
