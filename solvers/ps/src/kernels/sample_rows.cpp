#include "sample_rows.h"

#include "lane_math.h"

#include <algorithm>
#include <cmath>

namespace photorig::solvers::ps::internal {

PHOTORIG_PS_MULTIVERSION
void ReadRow(const RowInputs& in, double dark, const double* x, double* observed, double* inverse_sigma, double* chi2,
             int* usable) {
  const double x0 = x[0], x1 = x[1], x2 = x[2];
  // Fields in locals and one reduction type: otherwise GCC 12 leaves the loop scalar.
  const double* scales = in.scales;
  const double* inverse_scales = in.inverse_scales;
  const double* directions = in.directions;
  const double shadow = in.shadow_threshold, saturation = in.saturation_level;
  const double read_variance = in.read_variance, gain = in.shot_gain;
  const double* values = observed;
  double sum = 0.0, count = 0.0;
#pragma omp simd reduction(+ : sum, count)
  for (int k = 0; k < in.lights; ++k) {
    const double value = values[k];
    const double signal = value - dark;
    const bool ok = (signal > shadow) & (value < saturation);
    // b = signal / s has sigma sqrt(var(I)) / s. The square root and division
    // were most of this loop's time in double; a weight needs no more than
    // float's 7 digits, and float's are several times faster.
    const double b = ok ? signal * inverse_scales[k] : 0.0;
    const float variance = static_cast<float>(read_variance + gain * std::max(signal, 0.0));
    const double inverse = ok ? double(static_cast<float>(scales[k]) / std::sqrt(variance)) : 0.0;
    observed[k] = b;
    inverse_sigma[k] = inverse;
    const double r = (b - directions[3 * k] * x0 - directions[3 * k + 1] * x1 - directions[3 * k + 2] * x2) * inverse;
    sum += r * r;
    count += ok ? 1.0 : 0.0;
  }
  *chi2 = sum;
  *usable = static_cast<int>(count);
}

PHOTORIG_PS_MULTIVERSION
LitSums SumLitSamples(int lights, const double* wx, const double* wy, const double* wz, const double* observed,
                      const double* inverse_sigma, const double* x, const double* previous) {
  const double x0 = x[0], x1 = x[1], x2 = x[2], p0 = previous[0], p1 = previous[1], p2 = previous[2];
  double gxx = 0, gyy = 0, gzz = 0, gxy = 0, gxz = 0, gyz = 0, rx = 0, ry = 0, rz = 0;
  double chi2 = 0, used = 0, unlit = 0, moved = 0, worst_lit = 0, worst_unlit = 0;
#pragma omp simd reduction(+ : gxx, gyy, gzz, gxy, gxz, gyz, rx, ry, rz, chi2, used, unlit, moved) \
    reduction(max : worst_lit, worst_unlit)
  for (int k = 0; k < lights; ++k) {
    const double usable = inverse_sigma[k] != 0.0 ? 1.0 : 0.0;
    const double prediction = wx[k] * x0 + wy[k] * x1 + wz[k] * x2;
    const double lit = prediction > 0.0 ? usable : 0.0;
    const double was_lit = wx[k] * p0 + wy[k] * p1 + wz[k] * p2 > 0.0 ? usable : 0.0;
    const double u = inverse_sigma[k] * (observed[k] - prediction), u2 = u * u;  // 0 where unusable
    const double b = lit * observed[k];
    gxx += lit * wx[k] * wx[k], gyy += lit * wy[k] * wy[k], gzz += lit * wz[k] * wz[k];
    gxy += lit * wx[k] * wy[k], gxz += lit * wx[k] * wz[k], gyz += lit * wy[k] * wz[k];
    rx += b * wx[k], ry += b * wy[k], rz += b * wz[k];
    chi2 += lit * u2;
    used += lit;
    unlit += usable - lit;
    moved += lit != was_lit ? 1.0 : 0.0;
    worst_lit = std::max(worst_lit, lit * u2);
    worst_unlit = std::max(worst_unlit, (usable - lit) * u2);
  }
  return {gxx, gyy, gzz, gxy, gxz, gyz, rx, ry, rz, chi2, used, unlit, moved, worst_lit, worst_unlit};
}

}  // namespace photorig::solvers::ps::internal
