#include "photorig/solvers/lighting/spherical_harmonics.h"

#include <cmath>
#include <complex>

namespace photorig::solvers::lighting {

void EvaluateSh(int band, const Eigen::Vector3d& direction, double* out) {
  const double x = direction.x(), y = direction.y(), z = direction.z();
  // P_l^m(z) = sin^m(theta) Q_l^m(z); sin^m(theta) (cos m phi, sin m phi) = (x + i y)^m,
  // which keeps the poles free of atan2.
  std::complex<double> xy_power(1.0, 0.0);
  for (int m = 0; m <= band; ++m) {
    double double_factorial = 1.0;
    for (int k = 2 * m - 1; k > 1; k -= 2) double_factorial *= k;
    double q_prev = 0.0, q = double_factorial;  // Q_m^m
    for (int l = m; l <= band; ++l) {
      if (l > m) {
        const double q_next = l == m + 1 ? z * (2 * m + 1) * q
                                         : ((2 * l - 1) * z * q - (l + m - 1) * q_prev) / (l - m);
        q_prev = q;
        q = q_next;
      }
      double ratio = 1.0;  // (l - m)! / (l + m)!
      for (int k = l - m + 1; k <= l + m; ++k) ratio /= k;
      const double k_lm = std::sqrt((2 * l + 1) / (4.0 * M_PI) * ratio);
      if (m == 0) {
        out[l * l + l] = k_lm * q;
      } else {
        out[l * l + l + m] = std::sqrt(2.0) * k_lm * q * xy_power.real();
        out[l * l + l - m] = std::sqrt(2.0) * k_lm * q * xy_power.imag();
      }
    }
    xy_power *= std::complex<double>(x, y);
  }
}

Eigen::VectorXd EvaluateSh(int band, const Eigen::Vector3d& direction) {
  Eigen::VectorXd values(ShCoefficientCount(band));
  EvaluateSh(band, direction, values.data());
  return values;
}

double LambertianKernel(int l) {
  if (l == 0) return M_PI;
  if (l == 1) return 2.0 * M_PI / 3.0;
  if (l % 2 == 1) return 0.0;
  double factorial_ratio = 1.0;  // l! / (2^l ((l/2)!)^2)
  for (int k = 1; k <= l; ++k) factorial_ratio *= k;
  for (int k = 1; k <= l / 2; ++k) factorial_ratio /= static_cast<double>(k) * k;
  factorial_ratio /= std::pow(2.0, l);
  const double sign = (l / 2 - 1) % 2 == 0 ? 1.0 : -1.0;
  return 2.0 * M_PI * sign / ((l + 2.0) * (l - 1.0)) * factorial_ratio;
}

}  // namespace photorig::solvers::lighting
