#include "near_lambertian_sums.h"

#include <cmath>
#include <limits>

namespace photorig::solvers::ps::internal {
namespace {

// One light's samples of every lane. kProfile: the LED's cos^mu for mu != 1
// (as e^(mu ln cos)); mu = 1, the common Lambertian emitter, needs neither.
template <bool kProfile>
PHOTORIG_LANE_INLINE void AddLight(const NearLightTable& lights, int k, const float* plane, double shadow_threshold,
                                   double saturation_level, double read_variance, double shot_gain,
                                   const NearLanePixels& pixels, NearLaneSums& sums) {
  const double px = lights.position[3 * k], py = lights.position[3 * k + 1], pz = lights.position[3 * k + 2];
  const double ax = lights.axis[3 * k], ay = lights.axis[3 * k + 1], az = lights.axis[3 * k + 2];
  const double mu = lights.cos_exponent[k], constant = lights.constant[k];
#pragma omp simd
  for (int j = 0; j < kLanes; ++j) {
    const double value = plane[pixels.offset[j]];
    const double signal = value - pixels.dark[j];
    const double tx = px - pixels.x[j], ty = py - pixels.y[j], tz = pz - pixels.z[j];
    const double inverse_squared = 1.0 / (tx * tx + ty * ty + tz * tz);
    const double inverse = std::sqrt(inverse_squared);
    const double lx = tx * inverse, ly = ty * inverse, lz = tz * inverse;
    const double cos_axis = -(ax * lx + ay * ly + az * lz);
    double profile = cos_axis;
    if constexpr (kProfile) {
      double unused;
      profile = LaneExp(mu * LaneLogAndInverse(cos_axis > 1e-300 ? cos_axis : 1e-300, &unused));
    }
    // Behind the LED (cos_axis <= 0) the point is not lit: the sample says nothing.
    const double enters = (signal > shadow_threshold) & (value < saturation_level) & (cos_axis > 0.0) ? 1.0 : 0.0;
    const double gain = constant * profile * inverse_squared;
    const double weight = enters / (read_variance + shot_gain * (signal > 0.0 ? signal : 0.0));
    AddSample(sums.equations, j, weight, signal, gain * lx, gain * ly, gain * lz);
    sums.weighted_square_sum[j] += weight * signal * signal;
    sums.usable[j] += enters;
  }
}

}  // namespace

PHOTORIG_PS_MULTIVERSION
void NearLambertianSums(const NearLightTable& lights, const float* const* planes, const NearSampleRules& rules,
                        const NearLanePixels& pixels, NearLaneSums* out) {
  // The rules as plain numbers the lanes compare without branching: l2
  // takes every sample, and unit weights are a noise of variance 1.
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  const double shadow = rules.exclude_unusable ? rules.shadow_threshold : -kInfinity;
  const double saturation = rules.exclude_unusable ? rules.saturation_level : kInfinity;
  const double read_variance = rules.noise_known ? rules.read_variance : 1.0;
  const double shot_gain = rules.noise_known ? rules.shot_gain : 0.0;
  NearLaneSums sums = {};  // in registers; stored once at the end
  for (int k = 0; k < lights.count(); ++k) {
    if (lights.cos_exponent[k] == 1.0)
      AddLight<false>(lights, k, planes[k], shadow, saturation, read_variance, shot_gain, pixels, sums);
    else
      AddLight<true>(lights, k, planes[k], shadow, saturation, read_variance, shot_gain, pixels, sums);
  }
  *out = sums;
}

PHOTORIG_PS_MULTIVERSION
void SolveNearLanes(const NearLaneSums& sums, double max_condition_number, NearLaneSolutions* out) {
  const double max_condition4 = std::pow(max_condition_number, 4.0);  // |G|_F^2 |G^-1|_F^2 against cond(A)^4
  const auto& m = sums.equations.matrix;
  const auto& r = sums.equations.rhs;
  NearLaneSolutions solutions;
#pragma omp simd
  for (int j = 0; j < kLanes; ++j) {
    const double xx = m[0][j], xy = m[1][j], xz = m[2][j], yy = m[3][j], yz = m[4][j], zz = m[5][j];
    // The adjugate (G symmetric: six cofactors) and the determinant.
    const double a_xx = yy * zz - yz * yz, a_xy = xz * yz - xy * zz, a_xz = xy * yz - xz * yy;
    const double a_yy = xx * zz - xz * xz, a_yz = xy * xz - xx * yz, a_zz = xx * yy - xy * xy;
    const double det = xx * a_xx + xy * a_xy + xz * a_xz;
    const double inverse_det = det > 0.0 ? 1.0 / det : 0.0;
    const double bx = (a_xx * r[0][j] + a_xy * r[1][j] + a_xz * r[2][j]) * inverse_det;
    const double by = (a_xy * r[0][j] + a_yy * r[1][j] + a_yz * r[2][j]) * inverse_det;
    const double bz = (a_xz * r[0][j] + a_yz * r[1][j] + a_zz * r[2][j]) * inverse_det;
    const double frobenius2 = xx * xx + yy * yy + zz * zz + 2.0 * (xy * xy + xz * xz + yz * yz);
    const double adjugate2 = a_xx * a_xx + a_yy * a_yy + a_zz * a_zz + 2.0 * (a_xy * a_xy + a_xz * a_xz + a_yz * a_yz);
    const double bound4 = frobenius2 * adjugate2 * inverse_det * inverse_det;
    solutions.b[0][j] = bx, solutions.b[1][j] = by, solutions.b[2][j] = bz;
    const double chi_square = sums.weighted_square_sum[j] - (bx * r[0][j] + by * r[1][j] + bz * r[2][j]);
    solutions.chi_square[j] = chi_square > 0.0 ? chi_square : 0.0;
    solutions.conditioned[j] = (det > 0.0) & (bound4 <= max_condition4) ? 1.0 : 0.0;
  }
  *out = solutions;
}

}  // namespace photorig::solvers::ps::internal
