#pragma once
// The near-light Lambertian fit, one pixel per SIMD lane: each lane's
// surface point x sees LED k along its own unit vector l_k(x) and with its
// own relative irradiance f_k(x) (solvers/ps/near_lights.h), so unlike the
// distant fits no light matrix is shared; the kernel builds every sample's
// row s_k f_k(x) l_k(x) in the lane, sums the lane's weighted normal
// equations, solves them, and takes the chi-square from the residuals.

#include "lane_math.h"

#include <vector>

namespace photorig::solvers::ps::internal {

// The LEDs as plain arrays, kernels using no Eigen: per light its position
// (mm), emission axis (unit), cos exponent mu, the constant that turns
// cos^mu / d^2 into s_k f_k: s_k |p_k|^2 / cos_k(origin)^mu, and the
// position's homogeneous coordinate w (0: a light at infinity, its
// position the unit direction towards it).
struct NearLightTable {
  std::vector<double> position, axis;  // three per light
  std::vector<double> cos_exponent, constant, w;
  int count() const { return static_cast<int>(constant.size()); }
};

// Which samples enter and with what weight (the distant Lambertian method's
// rules): I - D at or below shadow_threshold is shadow, I at or above
// saturation_level clipped; both are left out unless exclude_unusable is
// false (l2). With a known noise each sample is weighted by 1 / Var(I - D).
struct NearSampleRules {
  double shadow_threshold = 0.0;
  double saturation_level = 0.0;
  bool exclude_unusable = true;
  bool noise_known = false;
  double read_variance = 0.0, shot_gain = 0.0;
};

// The pixels of one kernel pass: one AVX-512 register of floats.
inline constexpr int kNearLanes = kFloatLanes;

// kNearLanes pixels: their surface points (mm), dark levels, and the index
// of each pixel's sample in every light's image (all images share one
// layout).
struct alignas(64) NearLanePixels {
  float x[kNearLanes], y[kNearLanes], z[kNearLanes], dark[kNearLanes];
  int offset[kNearLanes];
};

// Each lane's fit: its normal equations G b = r (G = A^T W A; xx, xy, xz,
// yy, yz, zz), the samples that entered, b = G^-1 r by the adjugate and its
// length |b| (rho / pi) with its inverse, the chi-square sum
// c (I - D - row . b)^2 and the confidence it gives (the map's: min(1,
// dof / chi-square) with the noise known and a sample to spare, else 0),
// and a screen of the conditioning, cond(A)^2 = cond(G) <= |G|_F |G^-1|_F.
struct alignas(64) NearLaneFits {
  double matrix[6][kNearLanes];
  double rhs[3][kNearLanes];
  double usable[kNearLanes];
  double b[3][kNearLanes];
  double length[kNearLanes], inverse_length[kNearLanes];
  double chi_square[kNearLanes], confidence[kNearLanes];
  // 1: G is positive definite (det > 0) and the Frobenius bound keeps cond(A)
  // within the limit; 0: the bound does not, and only an exact test can tell.
  double conditioned[kNearLanes];
};

// planes[k]: light k's image. Lanes past the batch's end may repeat a pixel;
// their fits are ignored. *rows: the pass's scratch (each sample's weight,
// signal and row), kept between calls so that it is allocated once.
void FitNearLanes(const NearLightTable& lights, const float* const* planes, const NearSampleRules& rules,
                  double max_condition_number, const NearLanePixels& pixels, std::vector<float>* rows,
                  NearLaneFits* fits);

}  // namespace photorig::solvers::ps::internal
