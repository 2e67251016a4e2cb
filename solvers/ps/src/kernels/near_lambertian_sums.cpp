#include "near_lambertian_sums.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace photorig::solvers::ps::internal {
namespace {

// What one sample leaves in the scratch: its weight c, signal I - D and row
// s_k f_k(x) l_k(x), each as one register of lanes.
constexpr int kRowFields = 5;

// The lanes' float sums: G's six entries, r and the samples that entered.
// Float holds them well: every term of G is positive and of one scale, and
// the chi-square is not their difference (sum c (I - D)^2 - b . r, which
// float would lose at high signal-to-noise ratios) but summed from the
// residuals in a second pass.
struct alignas(64) FloatSums {
  float matrix[6][kNearLanes];
  float rhs[3][kNearLanes];
  float usable[kNearLanes];
};

// One light's samples of every lane into the sums and the scratch. The
// geometry runs in float: a light vector or gain off by one part in 10^7
// turns a normal by as many radians. kContiguous: the lanes' samples are
// neighbours in every plane, read as one vector. kProfile: the LED's cos^mu
// for mu != 1 (as e^(mu ln cos)); mu = 1, the common Lambertian emitter,
// needs neither that nor the distance itself.
template <bool kContiguous, bool kProfile>
PHOTORIG_LANE_INLINE void AddLight(const NearLightTable& lights, int k, const float* plane, float shadow_threshold,
                                   float saturation_level, float read_variance, float shot_gain,
                                   const NearLanePixels& pixels, float* row, FloatSums& sums) {
  const float px = static_cast<float>(lights.position[3 * k]), py = static_cast<float>(lights.position[3 * k + 1]),
              pz = static_cast<float>(lights.position[3 * k + 2]);
  const float ax = static_cast<float>(lights.axis[3 * k]), ay = static_cast<float>(lights.axis[3 * k + 1]),
              az = static_cast<float>(lights.axis[3 * k + 2]);
  const double mu = lights.cos_exponent[k];
  const float constant = static_cast<float>(lights.constant[k]), w = static_cast<float>(lights.w[k]);
  const float* first = plane + pixels.offset[0];
  // A lane batch reads each of the (tens of) planes at one place, more
  // streams than the hardware prefetchers follow: ask for the line the next
  // batch will read. Not further: the planes' lines at one offset share L1
  // sets, and lines fetched batches ahead are evicted before they are read.
  __builtin_prefetch(plane + pixels.offset[kNearLanes - 1] + kNearLanes);
  float* weight_out = row;
  float* signal_out = row + kNearLanes;
  float* gx_out = row + 2 * kNearLanes;
  float* gy_out = row + 3 * kNearLanes;
  float* gz_out = row + 4 * kNearLanes;
#pragma omp simd
  for (int j = 0; j < kNearLanes; ++j) {
    const float value = kContiguous ? first[j] : plane[pixels.offset[j]];
    const float signal = value - pixels.dark[j];
    // t: from the point to the LED, |t| = d; `along` = d cos_axis.
    const float tx = px - w * pixels.x[j], ty = py - w * pixels.y[j], tz = pz - w * pixels.z[j];
    const float d2 = tx * tx + ty * ty + tz * tz;
    const float along = -(ax * tx + ay * ty + az * tz);
    // The row s f l = constant cos^mu / d^2 (t / d). For mu = 1 that is
    // constant along t / d^4: no square root.
    float scale;
    if constexpr (kProfile) {
      const float inverse = 1.0f / std::sqrt(d2);
      const float cos_axis = along * inverse;
      double unused;
      const float profile = static_cast<float>(
          LaneExp(mu * LaneLogAndInverse(cos_axis > 1e-30f ? static_cast<double>(cos_axis) : 1e-30, &unused)));
      scale = constant * profile * inverse * inverse * inverse;
    } else {
      const float inverse_d2 = 1.0f / d2;
      scale = constant * along * inverse_d2 * inverse_d2;
    }
    // Behind the LED (cos_axis <= 0) the point is not lit: the sample says
    // nothing. A sample left out keeps a signal of 0, so that its weight of 0
    // meets finite numbers whatever the image holds.
    const bool enters = (signal > shadow_threshold) & (value < saturation_level) & (along > 0.0f);
    const float c = enters ? 1.0f / (read_variance + shot_gain * (signal > 0.0f ? signal : 0.0f)) : 0.0f;
    const float b = enters ? signal : 0.0f;
    const float gx = scale * tx, gy = scale * ty, gz = scale * tz;
    const float cx = c * gx, cy = c * gy, cz = c * gz;
    sums.matrix[0][j] += cx * gx, sums.matrix[1][j] += cx * gy, sums.matrix[2][j] += cx * gz;
    sums.matrix[3][j] += cy * gy, sums.matrix[4][j] += cy * gz, sums.matrix[5][j] += cz * gz;
    sums.rhs[0][j] += cx * b, sums.rhs[1][j] += cy * b, sums.rhs[2][j] += cz * b;
    sums.usable[j] += enters ? 1.0f : 0.0f;
    weight_out[j] = c, signal_out[j] = b, gx_out[j] = gx, gy_out[j] = gy, gz_out[j] = gz;
  }
}

template <bool kContiguous>
PHOTORIG_LANE_INLINE void AddLights(const NearLightTable& lights, const float* const* planes, float shadow,
                                    float saturation, float read_variance, float shot_gain,
                                    const NearLanePixels& pixels, float* rows, FloatSums& sums) {
  for (int k = 0; k < lights.count(); ++k) {
    float* row = rows + k * kRowFields * kNearLanes;
    if (lights.cos_exponent[k] == 1.0)
      AddLight<kContiguous, false>(lights, k, planes[k], shadow, saturation, read_variance, shot_gain, pixels, row, sums);
    else
      AddLight<kContiguous, true>(lights, k, planes[k], shadow, saturation, read_variance, shot_gain, pixels, row, sums);
  }
}

// Each lane's normal equations solved by the adjugate, with the screen of
// its conditioning.
PHOTORIG_LANE_INLINE void SolveLanes(const FloatSums& sums, double max_condition_number, NearLaneFits& fits) {
  const double max_condition2 = max_condition_number * max_condition_number;
  const double max_condition4 = max_condition2 * max_condition2;  // |G|_F^2 |G^-1|_F^2 against cond(A)^4
#pragma omp simd
  for (int j = 0; j < kNearLanes; ++j) {
    const double xx = sums.matrix[0][j], xy = sums.matrix[1][j], xz = sums.matrix[2][j], yy = sums.matrix[3][j],
                 yz = sums.matrix[4][j], zz = sums.matrix[5][j];
    const double rx = sums.rhs[0][j], ry = sums.rhs[1][j], rz = sums.rhs[2][j];
    // The adjugate (G symmetric: six cofactors) and the determinant.
    const double a_xx = yy * zz - yz * yz, a_xy = xz * yz - xy * zz, a_xz = xy * yz - xz * yy;
    const double a_yy = xx * zz - xz * xz, a_yz = xy * xz - xx * yz, a_zz = xx * yy - xy * xy;
    const double det = xx * a_xx + xy * a_xy + xz * a_xz;
    const double inverse_det = det > 0.0 ? 1.0 / det : 0.0;
    fits.b[0][j] = (a_xx * rx + a_xy * ry + a_xz * rz) * inverse_det;
    fits.b[1][j] = (a_xy * rx + a_yy * ry + a_yz * rz) * inverse_det;
    fits.b[2][j] = (a_xz * rx + a_yz * ry + a_zz * rz) * inverse_det;
    fits.length[j] = std::sqrt(fits.b[0][j] * fits.b[0][j] + fits.b[1][j] * fits.b[1][j] + fits.b[2][j] * fits.b[2][j]);
    fits.inverse_length[j] = 1.0 / fits.length[j];
    const double frobenius2 = xx * xx + yy * yy + zz * zz + 2.0 * (xy * xy + xz * xz + yz * yz);
    const double adjugate2 = a_xx * a_xx + a_yy * a_yy + a_zz * a_zz + 2.0 * (a_xy * a_xy + a_xz * a_xz + a_yz * a_yz);
    const double bound4 = frobenius2 * adjugate2 * inverse_det * inverse_det;
    fits.conditioned[j] = (det > 0.0) & (bound4 <= max_condition4) ? 1.0 : 0.0;
    for (int entry = 0; entry < 6; ++entry) fits.matrix[entry][j] = sums.matrix[entry][j];
    fits.rhs[0][j] = rx, fits.rhs[1][j] = ry, fits.rhs[2][j] = rz;
    fits.usable[j] = sums.usable[j];
  }
}

// sum c (I - D - row . b)^2 over the scratch: residuals of the noise's
// size, which float sums keep to its digits.
PHOTORIG_LANE_INLINE void ChiSquares(int light_count, const float* rows, bool noise_known, NearLaneFits& fits) {
  float bx[kNearLanes], by[kNearLanes], bz[kNearLanes], chi_square[kNearLanes] = {};
#pragma omp simd
  for (int j = 0; j < kNearLanes; ++j)
    bx[j] = static_cast<float>(fits.b[0][j]), by[j] = static_cast<float>(fits.b[1][j]),
    bz[j] = static_cast<float>(fits.b[2][j]);
  for (int k = 0; k < light_count; ++k) {
    const float* row = rows + k * kRowFields * kNearLanes;
#pragma omp simd
    for (int j = 0; j < kNearLanes; ++j) {
      const float residual = row[kNearLanes + j] - (row[2 * kNearLanes + j] * bx[j] + row[3 * kNearLanes + j] * by[j] +
                                                     row[4 * kNearLanes + j] * bz[j]);
      chi_square[j] += row[j] * residual * residual;
    }
  }
#pragma omp simd
  for (int j = 0; j < kNearLanes; ++j) {
    const double sum = chi_square[j] > 0.0f ? chi_square[j] : 0.0f, dof = fits.usable[j] - 3.0;
    fits.chi_square[j] = sum;
    fits.confidence[j] = noise_known && dof > 0.0 ? std::min(1.0, dof / std::max(sum, 1e-300)) : 0.0;
  }
}

}  // namespace

PHOTORIG_PS_MULTIVERSION
void FitNearLanes(const NearLightTable& lights, const float* const* planes, const NearSampleRules& rules,
                  double max_condition_number, const NearLanePixels& pixels, std::vector<float>* rows,
                  NearLaneFits* fits) {
  // The rules as plain numbers the lanes compare without branching: l2
  // takes every sample, and unit weights are a noise of variance 1.
  constexpr float kInfinity = std::numeric_limits<float>::infinity();
  const float shadow = rules.exclude_unusable ? static_cast<float>(rules.shadow_threshold) : -kInfinity;
  const float saturation = rules.exclude_unusable ? static_cast<float>(rules.saturation_level) : kInfinity;
  const float read_variance = rules.noise_known ? static_cast<float>(rules.read_variance) : 1.0f;
  const float shot_gain = rules.noise_known ? static_cast<float>(rules.shot_gain) : 0.0f;
  bool contiguous = true;
  for (int j = 1; j < kNearLanes; ++j) contiguous = contiguous && pixels.offset[j] == pixels.offset[0] + j;
  rows->resize(static_cast<std::size_t>(lights.count()) * kRowFields * kNearLanes);
  FloatSums sums = {};  // in registers; stored once at the end
  if (contiguous)
    AddLights<true>(lights, planes, shadow, saturation, read_variance, shot_gain, pixels, rows->data(), sums);
  else
    AddLights<false>(lights, planes, shadow, saturation, read_variance, shot_gain, pixels, rows->data(), sums);
  SolveLanes(sums, max_condition_number, *fits);
  ChiSquares(lights.count(), rows->data(), rules.noise_known, *fits);
}

}  // namespace photorig::solvers::ps::internal
