#include "near_lambertian_sums.h"

#include <cmath>
#include <limits>

namespace photorig::solvers::ps::internal {
namespace {

// One light's samples of every lane. The geometry runs in float: a light
// vector or gain off by one part in 10^7 turns a normal by as many radians,
// while a vector of floats holds twice the lanes and divides and takes
// square roots several times faster than one of doubles. The sums stay in
// double, since the chi-square is their difference sum c (I - D)^2 - b . r,
// which float would lose at high signal-to-noise ratios. kContiguous: the
// lanes' samples are neighbours in every plane, read as one vector.
// kProfile: the LED's cos^mu for mu != 1 (as e^(mu ln cos)); mu = 1, the
// common Lambertian emitter, needs neither.
template <bool kContiguous, bool kProfile>
PHOTORIG_LANE_INLINE void AddLight(const NearLightTable& lights, int k, const float* plane, float shadow_threshold,
                                   float saturation_level, float read_variance, float shot_gain,
                                   const NearLanePixels& pixels, NearLaneSums& sums) {
  const float px = static_cast<float>(lights.position[3 * k]), py = static_cast<float>(lights.position[3 * k + 1]),
              pz = static_cast<float>(lights.position[3 * k + 2]);
  const float ax = static_cast<float>(lights.axis[3 * k]), ay = static_cast<float>(lights.axis[3 * k + 1]),
              az = static_cast<float>(lights.axis[3 * k + 2]);
  const double mu = lights.cos_exponent[k];
  const float constant = static_cast<float>(lights.constant[k]), w = static_cast<float>(lights.w[k]);
  const float* first = plane + pixels.offset[0];
  // A lane batch reads each of the (tens of) planes at one place, more
  // streams than the hardware prefetchers follow: ask for the line the
  // batches four ahead will read.
  __builtin_prefetch(plane + pixels.offset[kLanes - 1] + 4 * kLanes);
#pragma omp simd
  for (int j = 0; j < kLanes; ++j) {
    const float value = kContiguous ? first[j] : plane[pixels.offset[j]];
    const float signal = value - pixels.dark[j];
    const float tx = px - w * pixels.x[j], ty = py - w * pixels.y[j], tz = pz - w * pixels.z[j];
    const float inverse = 1.0f / std::sqrt(tx * tx + ty * ty + tz * tz);
    const float lx = tx * inverse, ly = ty * inverse, lz = tz * inverse;
    const float cos_axis = -(ax * lx + ay * ly + az * lz);
    float profile = cos_axis;
    if constexpr (kProfile) {
      double unused;
      profile = static_cast<float>(
          LaneExp(mu * LaneLogAndInverse(cos_axis > 1e-30f ? static_cast<double>(cos_axis) : 1e-30, &unused)));
    }
    // Behind the LED (cos_axis <= 0) the point is not lit: the sample says nothing.
    const float enters = (signal > shadow_threshold) & (value < saturation_level) & (cos_axis > 0.0f) ? 1.0f : 0.0f;
    const float gain = constant * profile * inverse * inverse;
    const float weight = enters / (read_variance + shot_gain * (signal > 0.0f ? signal : 0.0f));
    const double c = weight, b = signal;
    AddSample(sums.equations, j, c, b, double(gain * lx), double(gain * ly), double(gain * lz));
    sums.weighted_square_sum[j] += c * b * b;
    sums.usable[j] += enters;
  }
}

template <bool kContiguous>
PHOTORIG_LANE_INLINE void AddLights(const NearLightTable& lights, const float* const* planes, float shadow,
                                    float saturation, float read_variance, float shot_gain,
                                    const NearLanePixels& pixels, NearLaneSums& sums) {
  for (int k = 0; k < lights.count(); ++k) {
    if (lights.cos_exponent[k] == 1.0)
      AddLight<kContiguous, false>(lights, k, planes[k], shadow, saturation, read_variance, shot_gain, pixels, sums);
    else
      AddLight<kContiguous, true>(lights, k, planes[k], shadow, saturation, read_variance, shot_gain, pixels, sums);
  }
}

}  // namespace

PHOTORIG_PS_MULTIVERSION
void NearLambertianSums(const NearLightTable& lights, const float* const* planes, const NearSampleRules& rules,
                        const NearLanePixels& pixels, NearLaneSums* out) {
  // The rules as plain numbers the lanes compare without branching: l2
  // takes every sample, and unit weights are a noise of variance 1.
  constexpr float kInfinity = std::numeric_limits<float>::infinity();
  const float shadow = rules.exclude_unusable ? static_cast<float>(rules.shadow_threshold) : -kInfinity;
  const float saturation = rules.exclude_unusable ? static_cast<float>(rules.saturation_level) : kInfinity;
  const float read_variance = rules.noise_known ? static_cast<float>(rules.read_variance) : 1.0f;
  const float shot_gain = rules.noise_known ? static_cast<float>(rules.shot_gain) : 0.0f;
  bool contiguous = true;
  for (int j = 1; j < kLanes; ++j) contiguous = contiguous && pixels.offset[j] == pixels.offset[0] + j;
  NearLaneSums sums = {};  // in registers; stored once at the end
  if (contiguous)
    AddLights<true>(lights, planes, shadow, saturation, read_variance, shot_gain, pixels, sums);
  else
    AddLights<false>(lights, planes, shadow, saturation, read_variance, shot_gain, pixels, sums);
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
