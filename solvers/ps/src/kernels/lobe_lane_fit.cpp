#include "lobe_lane_fit.h"

#include "lane_math.h"

#include "photorig/solvers/autodiff/ggx.h"
#include "photorig/solvers/autodiff/vector.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>

namespace photorig::solvers::ps::internal {
namespace {

constexpr double kInvPi = std::numbers::inv_pi;
// Relative precision of a cost the float evaluation returns: float rounding
// amplified by the exponent (h^e moves by e times h's rounding).
constexpr double kEvaluationPrecision = 1e-5;
// The grid start fits no lobe whose largest value over the samples is below
// this fraction of its peak (see BlinnPhongGridStartLanes).
constexpr double kVisibleLobe = 1e-6;
constexpr int kParameters = 5;  // two tangent-plane steps of the normal, rho_d, rho_s, e
constexpr int kHessianEntries = kParameters * (kParameters + 1) / 2;

// One point per lane: the unit normal with an orthonormal basis of its
// tangent plane, and the material.
struct alignas(64) LanePoint {
  double normal[3][kFloatLanes];
  double tangent[2][3][kFloatLanes];
  double diffuse_albedo[kFloatLanes], specular_albedo[kFloatLanes], exponent[kFloatLanes];
};

// Gauss-Newton normal equations of the weighted residuals at a LanePoint:
// cost = sum r^2, hessian = J^T J (upper triangle, row by row), gradient = J^T r.
struct alignas(64) LaneEquations {
  double cost[kFloatLanes];
  double hessian[kHessianEntries][kFloatLanes];
  double gradient[kParameters][kFloatLanes];
};

void CopyLane(const LanePoint& from, int lane, LanePoint* to) {
  for (int i = 0; i < 3; ++i) {
    to->normal[i][lane] = from.normal[i][lane];
    to->tangent[0][i][lane] = from.tangent[0][i][lane];
    to->tangent[1][i][lane] = from.tangent[1][i][lane];
  }
  to->diffuse_albedo[lane] = from.diffuse_albedo[lane];
  to->specular_albedo[lane] = from.specular_albedo[lane];
  to->exponent[lane] = from.exponent[lane];
}

// A view into its lane's column of a per-lane table, [i * kFloatLanes + lane].
void StoreLaneView(const Eigen::Vector3d& view, int lane, float* views) {
  for (int i = 0; i < 3; ++i) views[i * kFloatLanes + lane] = static_cast<float>(view[i]);
}

// The pass over the lights shared by all lanes: residuals r = (I - observed) / sigma
// and their derivatives, accumulated into the normal equations. Per light
// (blinn_phong_symbolic.h), with c = w . n, h = w_h . n, k = (e + 2) / (2 pi):
//   dI/dn = (rho_d / pi + rho_s k h^e) w + rho_s k e h^(e-1) c w_h,
//   dI/drho_d = c / pi, dI/drho_s = c k h^e, dI/de = c rho_s h^e (1 / (2 pi) + k ln h),
// all zero where c <= 0, the h terms zero where h <= 0. A tangent step t moves
// the normal by t to first order, so dI/dt = dI/dn . t.
// Row `row` of a table for lane j: one value all lanes share, or each lane's
// own at [row * kFloatLanes + j] (near lights, a perspective camera).
template <bool kPerLane>
PHOTORIG_LANE_INLINE float LaneEntry(const float* table, int row, int j) {
  if constexpr (kPerLane) {
    return table[row * kFloatLanes + j];
  } else {
    return table[row];
  }
}
// Entry i of light k's geometry (w then w_h) for lane j.
template <bool kPerLane>
PHOTORIG_LANE_INLINE float GeometryOf(const float* geometry, int k, int i, int j) {
  return LaneEntry<kPerLane>(geometry, 6 * k + i, j);
}

// Whether any lane's weight for a light is other than +0. A skipped light
// adds nothing to any lane's sums (its observed values are 0 too), so the
// passes skip it. One OR of the weights' bits: a compare per lane compiled
// to sixteen scalar compares (about a third as many instructions as a
// sample's arithmetic), and with it the GGX pass's lane loop stayed scalar.
PHOTORIG_LANE_INLINE bool AnyLaneUses(const float* inverse_sigma) {
  std::uint32_t bits = 0;
#pragma omp simd reduction(| : bits)
  for (int j = 0; j < kFloatLanes; ++j) bits |= std::bit_cast<std::uint32_t>(inverse_sigma[j]);
  return bits != 0;
}

// One sample's residual r and derivatives d0..d4 into lane j's sums:
// r^2, J^T J's upper triangle, J^T r (LaneEquations' order).
using LaneSums = float[1 + kHessianEntries + kParameters][kFloatLanes];
PHOTORIG_LANE_INLINE void AddSample(LaneSums& acc, int j, float r, float d0, float d1, float d2, float d3, float d4) {
  // Written out: loops here would stop GCC vectorising over the lanes.
  acc[0][j] += r * r;
  acc[1][j] += d0 * d0, acc[2][j] += d0 * d1, acc[3][j] += d0 * d2, acc[4][j] += d0 * d3, acc[5][j] += d0 * d4;
  acc[6][j] += d1 * d1, acc[7][j] += d1 * d2, acc[8][j] += d1 * d3, acc[9][j] += d1 * d4;
  acc[10][j] += d2 * d2, acc[11][j] += d2 * d3, acc[12][j] += d2 * d4;
  acc[13][j] += d3 * d3, acc[14][j] += d3 * d4;
  acc[15][j] += d4 * d4;
  acc[16][j] += d0 * r, acc[17][j] += d1 * r, acc[18][j] += d2 * r, acc[19][j] += d3 * r, acc[20][j] += d4 * r;
}

void StoreSums(const LaneSums& acc, LaneEquations* out) {
  for (int j = 0; j < kFloatLanes; ++j) {
    out->cost[j] = acc[0][j];
    for (int e = 0; e < kHessianEntries; ++e) out->hessian[e][j] = acc[1 + e][j];
    for (int p = 0; p < kParameters; ++p) out->gradient[p][j] = acc[1 + kHessianEntries + p][j];
  }
}

// A LanePoint in float, one array per quantity, so that each lane loop reads
// whole registers.
struct alignas(64) FloatLanePoint {
  float nx[kFloatLanes], ny[kFloatLanes], nz[kFloatLanes], t[2][3][kFloatLanes];
  float rho_d[kFloatLanes], rho_s[kFloatLanes], shape[kFloatLanes];  // shape: e or a
};
PHOTORIG_LANE_INLINE void ToFloat(const LanePoint& q, FloatLanePoint* f) {
#pragma omp simd
  for (int j = 0; j < kFloatLanes; ++j) {
    f->nx[j] = static_cast<float>(q.normal[0][j]), f->ny[j] = static_cast<float>(q.normal[1][j]);
    f->nz[j] = static_cast<float>(q.normal[2][j]);
    for (int i = 0; i < 3; ++i)
      f->t[0][i][j] = static_cast<float>(q.tangent[0][i][j]), f->t[1][i][j] = static_cast<float>(q.tangent[1][i][j]);
    f->rho_d[j] = static_cast<float>(q.diffuse_albedo[j]), f->rho_s[j] = static_cast<float>(q.specular_albedo[j]);
    f->shape[j] = static_cast<float>(q.exponent[j]);
  }
}

template <bool kPerLane>
PHOTORIG_LANE_INLINE void EvaluateLanesOf(const LanePoint& q, int lights, const float* geometry, const float* observed,
                                          const float* inverse_sigma, LaneEquations* out) {
  constexpr float kInvPiF = static_cast<float>(kInvPi);
  FloatLanePoint point;
  ToFloat(q, &point);
  const auto &nx = point.nx, &ny = point.ny, &nz = point.nz, &rho_d = point.rho_d, &rho_s = point.rho_s;
  const auto& t = point.t;
  const auto& exponent = point.shape;
  alignas(64) float lobe_scale[kFloatLanes];
#pragma omp simd
  for (int j = 0; j < kFloatLanes; ++j) {
    lobe_scale[j] = static_cast<float>(q.specular_albedo[j] * (q.exponent[j] + 2.0) * (0.5 * kInvPi));
  }
  alignas(64) LaneSums acc = {};
  for (int k = 0; k < lights; ++k) {
    const float* sigma_k = inverse_sigma + k * kFloatLanes;
    if (!AnyLaneUses(sigma_k)) continue;  // shadowed in every lane
    const float* observed_k = observed + k * kFloatLanes;
#pragma omp simd
    for (int j = 0; j < kFloatLanes; ++j) {
      const float wx = GeometryOf<kPerLane>(geometry, k, 0, j), wy = GeometryOf<kPerLane>(geometry, k, 1, j);
      const float wz = GeometryOf<kPerLane>(geometry, k, 2, j), hx = GeometryOf<kPerLane>(geometry, k, 3, j);
      const float hy = GeometryOf<kPerLane>(geometry, k, 4, j), hz = GeometryOf<kPerLane>(geometry, k, 5, j);
      const float c = wx * nx[j] + wy * ny[j] + wz * nz[j];
      const float h = hx * nx[j] + hy * ny[j] + hz * nz[j];
      // Clamps as max() and two selects: GCC gives up on a lane loop with more conditions.
      const float lit_c = std::max(c, 0.0f);
      const float safe_h = std::max(h, 1e-30f);  // h <= 0: lobe <= 1e-30 e, nothing
      float inverse_h;
      const float log_h = LaneLogAndInverse(safe_h, &inverse_h);
      const float lobe = LaneExp(exponent[j] * log_h);
      const float brdf = rho_d[j] * kInvPiF + lobe_scale[j] * lobe;
      const float sigma = sigma_k[j];
      const float r = (brdf * lit_c - observed_k[j]) * sigma;
      const float cs = lit_c * sigma;
      // dI/dn / sigma = a w + s w_h; the w_h term vanishes with the clamp of h.
      const float a = c > 0.0f ? brdf * sigma : 0.0f;
      const float s = h > 0.0f ? lobe_scale[j] * exponent[j] * lobe * inverse_h * cs : 0.0f;
      const float w_t1 = wx * t[0][0][j] + wy * t[0][1][j] + wz * t[0][2][j];
      const float w_t2 = wx * t[1][0][j] + wy * t[1][1][j] + wz * t[1][2][j];
      const float h_t1 = hx * t[0][0][j] + hy * t[0][1][j] + hz * t[0][2][j];
      const float h_t2 = hx * t[1][0][j] + hy * t[1][1][j] + hz * t[1][2][j];
      const float d0 = a * w_t1 + s * h_t1, d1 = a * w_t2 + s * h_t2, d2 = cs * kInvPiF;
      const float d3 = cs * (exponent[j] + 2.0f) * (0.5f * kInvPiF) * lobe;
      const float d4 = cs * rho_s[j] * lobe * (0.5f * kInvPiF + (exponent[j] + 2.0f) * (0.5f * kInvPiF) * log_h);
      AddSample(acc, j, r, d0, d1, d2, d3, d4);
    }
  }
  StoreSums(acc, out);
}

// G1(c) = 2 c / (c + r), r = sqrt(a^2 + (1 - a^2) c^2), with dG1/dc =
// 2 a^2 / (r (c + r)^2) and dG1/d(a^2) = -c (1 - c^2) / (r (c + r)^2)
// (autodiff::GgxG1); c > 0.
PHOTORIG_LANE_INLINE void LaneGgxG1(float c, float a2, float* value, float* d_cos, float* d_a2) {
  const float r = std::sqrt(a2 + (1.0f - a2) * c * c), sum = c + r;
  const float q = 1.0f / (r * sum * sum);
  *value = 2.0f * c / sum, *d_cos = 2.0f * a2 * q, *d_a2 = -c * (1.0f - c * c) * q;
}

// The GGX lobe's pass (autodiff::SymbolicGgxJacobian in lanes); the geometry
// and the view v (three rows) shared or each lane's, as in EvaluateLanesOf.
// The lobe per unit rho_s is S G1(c) / t^2 with the per-pixel
// S = a^2 G1(v . n) / (4 pi v . n) and t = h^2 (a^2 - 1) + 1, c = w . n,
// h = max(0, w_h . n); zero where v . n <= 0 (no lobe faces the camera).
//   dI/dn = (rho_d / pi + rho_s S G1'(c) / t^2) w + rho_s S'(v.n) G1(c) / t^2 v
//           - 4 rho_s S G1(c) h (a^2 - 1) / t^3 w_h,
//   dI/da = 2 a rho_s (S_a2 G1 / t^2 + S G1_a2 / t^2 - 2 S G1 h^2 / t^3),
// all zero where c <= 0.
template <bool kPerLane>
PHOTORIG_LANE_INLINE void EvaluateGgxLanesOf(const LanePoint& q, int lights, const float* geometry, const float* view,
                                             const float* observed, const float* inverse_sigma, LaneEquations* out) {
  constexpr float kInvPiF = static_cast<float>(kInvPi);
  FloatLanePoint point;
  ToFloat(q, &point);
  const auto &nx = point.nx, &ny = point.ny, &nz = point.nz, &rho_d = point.rho_d, &rho_s = point.rho_s;
  const auto& t = point.t;
  alignas(64) float a2[kFloatLanes], two_a[kFloatLanes];
  alignas(64) float s_unit[kFloatLanes], s_d_cos_view[kFloatLanes], s_d_a2[kFloatLanes], v_t[2][kFloatLanes];
#pragma omp simd
  for (int j = 0; j < kFloatLanes; ++j) {
    const float a = point.shape[j];
    a2[j] = a * a, two_a[j] = 2.0f * a;
    // One select, the other clamps as max(): GCC gives up on a lane loop with more conditions.
    const float vx = LaneEntry<kPerLane>(view, 0, j), vy = LaneEntry<kPerLane>(view, 1, j);
    const float vz = LaneEntry<kPerLane>(view, 2, j);
    const float cos_view = vx * nx[j] + vy * ny[j] + vz * nz[j];
    const float lobe = cos_view > 0.0f ? 1.0f : 0.0f;
    const float safe_cos_view = std::max(cos_view, 1e-6f);  // what it gives is multiplied by lobe
    float g, g_d_cos, g_d_a2;
    LaneGgxG1(safe_cos_view, a2[j], &g, &g_d_cos, &g_d_a2);
    const float k = lobe * 0.25f * kInvPiF / safe_cos_view;
    s_unit[j] = k * a2[j] * g;
    s_d_cos_view[j] = k * a2[j] * (g_d_cos - g / safe_cos_view);
    s_d_a2[j] = k * (g + a2[j] * g_d_a2);
    v_t[0][j] = vx * t[0][0][j] + vy * t[0][1][j] + vz * t[0][2][j];
    v_t[1][j] = vx * t[1][0][j] + vy * t[1][1][j] + vz * t[1][2][j];
  }
  alignas(64) LaneSums acc = {};
  for (int k = 0; k < lights; ++k) {
    const float* sigma_k = inverse_sigma + k * kFloatLanes;
    if (!AnyLaneUses(sigma_k)) continue;  // shadowed in every lane
    const float* observed_k = observed + k * kFloatLanes;
#pragma omp simd
    for (int j = 0; j < kFloatLanes; ++j) {
      const float wx = GeometryOf<kPerLane>(geometry, k, 0, j), wy = GeometryOf<kPerLane>(geometry, k, 1, j);
      const float wz = GeometryOf<kPerLane>(geometry, k, 2, j), hx = GeometryOf<kPerLane>(geometry, k, 3, j);
      const float hy = GeometryOf<kPerLane>(geometry, k, 4, j), hz = GeometryOf<kPerLane>(geometry, k, 5, j);
      const float c = wx * nx[j] + wy * ny[j] + wz * nz[j];
      const float h = std::max(hx * nx[j] + hy * ny[j] + hz * nz[j], 0.0f);
      // As above: one select; the clamped cosines' terms are multiplied by lit.
      const float lit = c > 0.0f ? 1.0f : 0.0f;
      const float lit_c = std::max(c, 0.0f), safe_c = std::max(c, 1e-6f);
      const float inverse_t = 1.0f / (h * h * (a2[j] - 1.0f) + 1.0f), inverse_t2 = inverse_t * inverse_t;
      float g, g_d_cos, g_d_a2;
      LaneGgxG1(safe_c, a2[j], &g, &g_d_cos, &g_d_a2);
      const float unit = lit * s_unit[j] * g * inverse_t2;  // the lobe per unit rho_s
      const float sigma = sigma_k[j], lit_sigma = lit * sigma;
      const float r = ((rho_d[j] * kInvPiF) * lit_c + rho_s[j] * unit - observed_k[j]) * sigma;
      const float along_w = (rho_d[j] * kInvPiF + rho_s[j] * s_unit[j] * g_d_cos * inverse_t2) * lit_sigma;
      const float along_v = rho_s[j] * s_d_cos_view[j] * g * inverse_t2 * lit_sigma;
      const float along_h = -4.0f * rho_s[j] * s_unit[j] * g * h * (a2[j] - 1.0f) * inverse_t2 * inverse_t * lit_sigma;
      const float w_t1 = wx * t[0][0][j] + wy * t[0][1][j] + wz * t[0][2][j];
      const float w_t2 = wx * t[1][0][j] + wy * t[1][1][j] + wz * t[1][2][j];
      const float h_t1 = hx * t[0][0][j] + hy * t[0][1][j] + hz * t[0][2][j];
      const float h_t2 = hx * t[1][0][j] + hy * t[1][1][j] + hz * t[1][2][j];
      const float d0 = along_w * w_t1 + along_v * v_t[0][j] + along_h * h_t1;
      const float d1 = along_w * w_t2 + along_v * v_t[1][j] + along_h * h_t2;
      const float d2 = lit_c * kInvPiF * sigma, d3 = unit * sigma;
      const float d4 = two_a[j] * rho_s[j] * inverse_t2 *
                       (s_d_a2[j] * g + s_unit[j] * g_d_a2 - 2.0f * s_unit[j] * g * h * h * inverse_t) * lit_sigma;
      AddSample(acc, j, r, d0, d1, d2, d3, d4);
    }
  }
  StoreSums(acc, out);
}

// view: GGX's, towards the camera (the Blinn-Phong pass has it in its half vectors).
PHOTORIG_PS_MULTIVERSION
void EvaluateLanes(LaneLobe lobe, bool per_lane, const LanePoint& q, int lights, const float* geometry,
                   const float* view, const float* observed, const float* inverse_sigma, LaneEquations* out) {
  if (lobe == LaneLobe::kGgx && per_lane)
    EvaluateGgxLanesOf<true>(q, lights, geometry, view, observed, inverse_sigma, out);
  else if (lobe == LaneLobe::kGgx)
    EvaluateGgxLanesOf<false>(q, lights, geometry, view, observed, inverse_sigma, out);
  else if (per_lane)
    EvaluateLanesOf<true>(q, lights, geometry, observed, inverse_sigma, out);
  else
    EvaluateLanesOf<false>(q, lights, geometry, observed, inverse_sigma, out);
}

// The damped Gauss-Newton step of every lane from its current point p:
// (H + lambda diag(H) + 1e-12 I) step = g by Cholesky, then the candidate
// q = p - step (the normal renormalised, the material projected onto its
// bounds: e's or a's are min_shape and max_shape). positive[j] is 0 where the damped matrix is not positive definite
// (raise lambda and try again); predicted[j] is the decrease of the cost the
// linearised model promises, 2 step.g - step.H.step.
PHOTORIG_PS_MULTIVERSION
void ProposeLanes(const LanePoint& p, const LaneEquations& eq, const double* lambda, double min_shape,
                  double max_shape, LanePoint* q, double* positive, double* predicted) {
  // Lower triangle of the factor, [row][col][lane]; loops over the matrix
  // indices stay outside the lane loops so that each lane loop vectorises.
  alignas(64) double l[kParameters][kParameters][kFloatLanes];
  alignas(64) double step[kParameters][kFloatLanes];
  auto hessian_entry = [](int row, int col) {  // index into the packed upper triangle
    if (row > col) std::swap(row, col);
    return row * kParameters - row * (row - 1) / 2 + (col - row);
  };
  // Every lane loop below is free of inner loops: GCC does not vectorise
  // one that has them.
  alignas(64) double sum[kFloatLanes];
#pragma omp simd
  for (int j = 0; j < kFloatLanes; ++j) positive[j] = 1.0;
  for (int col = 0; col < kParameters; ++col) {
    const int diagonal_entry = hessian_entry(col, col);
#pragma omp simd
    for (int j = 0; j < kFloatLanes; ++j) {
      const double h = eq.hessian[diagonal_entry][j];
      sum[j] = h + lambda[j] * h + 1e-12;
    }
    for (int i = 0; i < col; ++i) {
#pragma omp simd
      for (int j = 0; j < kFloatLanes; ++j) sum[j] -= l[col][i][j] * l[col][i][j];
    }
#pragma omp simd
    for (int j = 0; j < kFloatLanes; ++j) {
      const bool ok = sum[j] > 0.0;
      positive[j] = ok ? positive[j] : 0.0;
      l[col][col][j] = std::sqrt(ok ? sum[j] : 1.0);
    }
    for (int row = col + 1; row < kParameters; ++row) {
      const int entry = hessian_entry(row, col);
#pragma omp simd
      for (int j = 0; j < kFloatLanes; ++j) sum[j] = eq.hessian[entry][j];
      for (int i = 0; i < col; ++i) {
#pragma omp simd
        for (int j = 0; j < kFloatLanes; ++j) sum[j] -= l[row][i][j] * l[col][i][j];
      }
#pragma omp simd
      for (int j = 0; j < kFloatLanes; ++j) l[row][col][j] = sum[j] / l[col][col][j];
    }
  }
  for (int row = 0; row < kParameters; ++row) {  // L y = g
#pragma omp simd
    for (int j = 0; j < kFloatLanes; ++j) sum[j] = eq.gradient[row][j];
    for (int i = 0; i < row; ++i) {
#pragma omp simd
      for (int j = 0; j < kFloatLanes; ++j) sum[j] -= l[row][i][j] * step[i][j];
    }
#pragma omp simd
    for (int j = 0; j < kFloatLanes; ++j) step[row][j] = sum[j] / l[row][row][j];
  }
  for (int row = kParameters - 1; row >= 0; --row) {  // L^T step = y
#pragma omp simd
    for (int j = 0; j < kFloatLanes; ++j) sum[j] = step[row][j];
    for (int i = row + 1; i < kParameters; ++i) {
#pragma omp simd
      for (int j = 0; j < kFloatLanes; ++j) sum[j] -= l[i][row][j] * step[i][j];
    }
#pragma omp simd
    for (int j = 0; j < kFloatLanes; ++j) step[row][j] = sum[j] / l[row][row][j];
  }
#pragma omp simd
  for (int j = 0; j < kFloatLanes; ++j) predicted[j] = 0.0;
  for (int row = 0; row < kParameters; ++row) {
#pragma omp simd
    for (int j = 0; j < kFloatLanes; ++j) predicted[j] += 2.0 * step[row][j] * eq.gradient[row][j];
    for (int col = row; col < kParameters; ++col) {
      const int entry = hessian_entry(row, col);
      const double factor = row == col ? 1.0 : 2.0;
#pragma omp simd
      for (int j = 0; j < kFloatLanes; ++j) predicted[j] -= factor * step[row][j] * step[col][j] * eq.hessian[entry][j];
    }
  }
#pragma omp simd
  for (int j = 0; j < kFloatLanes; ++j) {
    const double step_t1 = step[0][j], step_t2 = step[1][j];
    const double nx = p.normal[0][j] - step_t1 * p.tangent[0][0][j] - step_t2 * p.tangent[1][0][j];
    const double ny = p.normal[1][j] - step_t1 * p.tangent[0][1][j] - step_t2 * p.tangent[1][1][j];
    const double nz = p.normal[2][j] - step_t1 * p.tangent[0][2][j] - step_t2 * p.tangent[1][2][j];
    const double inverse_length = 1.0 / std::sqrt(nx * nx + ny * ny + nz * nz);
    const double ux = nx * inverse_length, uy = ny * inverse_length, uz = nz * inverse_length;
    const TangentPair<double> t = TangentBasis(ux, uy, uz);
    q->normal[0][j] = ux, q->normal[1][j] = uy, q->normal[2][j] = uz;
    q->tangent[0][0][j] = t.t1[0], q->tangent[0][1][j] = t.t1[1], q->tangent[0][2][j] = t.t1[2];
    q->tangent[1][0][j] = t.t2[0], q->tangent[1][1][j] = t.t2[1], q->tangent[1][2][j] = t.t2[2];
    q->diffuse_albedo[j] = std::max(0.0, p.diffuse_albedo[j] - step[2][j]);
    q->specular_albedo[j] = std::max(0.0, p.specular_albedo[j] - step[3][j]);
    q->exponent[j] = std::min(std::max(p.exponent[j] - step[4][j], min_shape), max_shape);
  }
}

// A lane whose lobe is held (a region's shared lobe) has no derivatives
// along rho_s and e: their rows and columns of J^T J and entries of J^T r
// are zero, so the damped step (whose diagonal keeps 1e-12) leaves them
// where they are and solves for the normal and rho_d alone.
void HoldSharedLobes(const double* shared_exponent, LaneEquations* equations) {
  constexpr int kFirstLobeParameter = 3;  // rho_s, then e
  for (int j = 0; j < kFloatLanes; ++j) {
    if (!(shared_exponent[j] > 0.0)) continue;
    for (int row = 0, entry = 0; row < kParameters; ++row)
      for (int col = row; col < kParameters; ++col, ++entry)
        if (col >= kFirstLobeParameter) equations->hessian[entry][j] = 0.0;
    for (int p = kFirstLobeParameter; p < kParameters; ++p) equations->gradient[p][j] = 0.0;
  }
}

}  // namespace

// With d = cos / pi and l = k h^e cos, k = (e + 2) / (2 pi), the normal
// equations' sums are dd = S_A / pi^2, db = S_B / pi, dl = k / pi S_A h^e,
// ll = k^2 S_A h^2e and lb = k S_B h^e, where S_A sums weight cos^2 and S_B
// weight cos b over the samples. A = weight cos^2 and B = weight cos b are
// computed once, into cos_light and observed; each grid point then takes
// three multiply-adds and the squaring per sample.
PHOTORIG_PS_MULTIVERSION
void BlinnPhongGridStartLanes(int lights, double* cos_light, double* cos_half, double* observed, const double* weight,
                              const double* start_albedo, double min_exponent, double max_exponent,
                              LaneMaterial* out) {
  double exponent = 1.0;
  const int samples = lights * kFloatLanes;
  while (exponent < min_exponent) {
    exponent *= 2.0;
#pragma omp simd
    for (int i = 0; i < samples; ++i) cos_half[i] *= cos_half[i];
  }
  // peak: the lobe's largest value h^e over the samples the fit uses.
  alignas(64) double sum_a[kFloatLanes] = {}, sum_b[kFloatLanes] = {}, bb[kFloatLanes] = {}, peak[kFloatLanes] = {};
  for (int k = 0; k < lights; ++k) {
    const double* c = weight + k * kFloatLanes;
    const double* h = cos_half + k * kFloatLanes;
    double* a = cos_light + k * kFloatLanes;
    double* b = observed + k * kFloatLanes;
#pragma omp simd
    for (int j = 0; j < kFloatLanes; ++j) {
      const double cosine = a[j], weighted_cosine = c[j] * cosine;
      bb[j] += c[j] * b[j] * b[j];
      a[j] = weighted_cosine * cosine, b[j] = weighted_cosine * b[j];
      sum_a[j] += a[j], sum_b[j] += b[j];
      peak[j] = std::max(peak[j], a[j] > 0.0 ? h[j] : 0.0);
    }
  }
  alignas(64) double best_chi2[kFloatLanes];
  for (int j = 0; j < kFloatLanes; ++j) {
    best_chi2[j] = std::numeric_limits<double>::infinity();
    out->diffuse_albedo[j] = start_albedo[j], out->specular_albedo[j] = 0.0, out->exponent[j] = exponent;
  }
  for (; exponent <= max_exponent; exponent *= 2.0) {
    alignas(64) double sum_a_h[kFloatLanes] = {}, sum_a_h2[kFloatLanes] = {}, sum_b_h[kFloatLanes] = {};
    for (int k = 0; k < lights; ++k) {
      const double* a = cos_light + k * kFloatLanes;
      const double* b = observed + k * kFloatLanes;
      double* h = cos_half + k * kFloatLanes;
#pragma omp simd
      for (int j = 0; j < kFloatLanes; ++j) {
        const double h2 = h[j] * h[j];
        sum_a_h[j] += a[j] * h[j], sum_a_h2[j] += a[j] * h2, sum_b_h[j] += b[j] * h[j];
        h[j] = h2;  // the next grid point's lobe
      }
    }
    const double normalisation = (exponent + 2.0) / (2.0 * M_PI);
    for (int j = 0; j < kFloatLanes; ++j) {
      const double dd = sum_a[j] * (kInvPi * kInvPi), db = sum_b[j] * kInvPi;
      const double dl = normalisation * kInvPi * sum_a_h[j], ll = normalisation * normalisation * sum_a_h2[j];
      const double lb = normalisation * sum_b_h[j];
      const double det = dd * ll - dl * dl;
      double rho_d = dd > 0.0 ? db / dd : 0.0, rho_s = 0.0;
      // A lobe that stays below kVisibleLobe of its peak at every sample is
      // fitted to its far tail: its rho_s grows as 1 / h^e (past 1e40 at the
      // rim of a shiny sphere, where every h is small), beyond what the lane
      // fitter's float evaluation can hold.
      if (peak[j] >= kVisibleLobe && det > 1e-12 * dd * ll) {
        const double joint_s = (dd * lb - dl * db) / det;
        if (joint_s > 0.0) rho_s = joint_s, rho_d = (ll * db - dl * lb) / det;
      }
      const double chi2 = bb[j] - 2.0 * (rho_d * db + rho_s * lb) + rho_d * rho_d * dd + 2.0 * rho_d * rho_s * dl +
                          rho_s * rho_s * ll;
      if (chi2 < best_chi2[j] && rho_d >= 0.0) {
        best_chi2[j] = chi2;
        out->diffuse_albedo[j] = rho_d, out->specular_albedo[j] = rho_s, out->exponent[j] = exponent;
      }
      peak[j] *= peak[j];
    }
  }
}

PHOTORIG_PS_MULTIVERSION
void BlinnPhongSharedStartLanes(int lights, const double* cos_light, const double* cos_half, const double* observed,
                                const double* weight, const double* start_albedo, const double* specular_albedo,
                                const double* exponent, LaneMaterial* out) {
  // rho_d / pi = sum w c (b - lobe c) / sum w c^2, with lobe = rho_s (e + 2) / (2 pi) h^e.
  alignas(64) double sum_a[kFloatLanes] = {}, sum_b[kFloatLanes] = {};
  for (int k = 0; k < lights; ++k) {
    const double* w = weight + k * kFloatLanes;
    const double* c = cos_light + k * kFloatLanes;
    const double* h = cos_half + k * kFloatLanes;
    const double* b = observed + k * kFloatLanes;
    // h^e as exp(e ln h) in the lanes' own log and exp: std::pow here, one
    // scalar call per sample and lane, was 6 % of a glossy object's solve.
#pragma omp simd
    for (int j = 0; j < kFloatLanes; ++j) {
      double unused;
      const double safe_h = h[j] > 1e-300 ? h[j] : 1e-300;  // a value, not std::max's reference: it vectorises
      const double power = LaneExp(exponent[j] * LaneLogAndInverse(safe_h, &unused));
      const double lobe =
          h[j] > 0.0 && exponent[j] > 0.0 ? specular_albedo[j] * (exponent[j] + 2.0) * (0.5 * kInvPi) * power : 0.0;
      sum_a[j] += w[j] * c[j] * c[j], sum_b[j] += w[j] * c[j] * (b[j] - lobe * c[j]);
    }
  }
  for (int j = 0; j < kFloatLanes; ++j) {
    out->diffuse_albedo[j] = sum_a[j] > 0.0 ? std::max(0.0, M_PI * sum_b[j] / sum_a[j]) : start_albedo[j];
    out->specular_albedo[j] = specular_albedo[j], out->exponent[j] = exponent[j];
  }
}

namespace {

// GGX's start material at each lane's normal: for each roughness of the
// grid, rho_d and rho_s >= 0 by weighted least squares in the model's two
// linear columns (c / pi and the lobe per unit rho_s); the grid point with
// the lowest chi-square wins, else rho_d = start_albedo with no lobe.
// cos_light and cos_half are max(0, w . n) and max(0, w_h . n) per sample;
// an unlit sample (c = 0) has G1 = 0, so neither column has it.
PHOTORIG_PS_MULTIVERSION
void GgxGridStartLanes(int lights, const double* cos_light, const double* cos_half, const double* cos_view,
                       const double* observed, const double* weight, const double* start_albedo, LaneMaterial* out) {
  alignas(64) double bb[kFloatLanes] = {}, best_chi2[kFloatLanes];
  for (int j = 0; j < kFloatLanes; ++j) {
    best_chi2[j] = std::numeric_limits<double>::infinity();
    out->diffuse_albedo[j] = start_albedo[j], out->specular_albedo[j] = 0.0, out->exponent[j] = kGgxStartRoughness[5];
  }
  for (int k = 0; k < lights; ++k) {
    const double* w = weight + k * kFloatLanes;
    const double* b = observed + k * kFloatLanes;
#pragma omp simd
    for (int j = 0; j < kFloatLanes; ++j) bb[j] += w[j] * b[j] * b[j];
  }
  for (const double roughness : kGgxStartRoughness) {
    const double a2 = roughness * roughness;
    // S = a^2 G1(v . n) / (4 pi v . n), 0 where the lobe faces away.
    alignas(64) double s_unit[kFloatLanes], dd[kFloatLanes] = {}, dl[kFloatLanes] = {}, ll[kFloatLanes] = {},
                                            db[kFloatLanes] = {}, lb[kFloatLanes] = {};
    for (int j = 0; j < kFloatLanes; ++j)
      s_unit[j] = cos_view[j] > 0.0 ? a2 * solvers::autodiff::GgxG1(cos_view[j], a2).value * 0.25 * kInvPi / cos_view[j]
                                    : 0.0;
    for (int k = 0; k < lights; ++k) {
      const double* c = cos_light + k * kFloatLanes;
      const double* h = cos_half + k * kFloatLanes;
      const double* w = weight + k * kFloatLanes;
      const double* b = observed + k * kFloatLanes;
#pragma omp simd
      for (int j = 0; j < kFloatLanes; ++j) {
        // The lobe S G1(c) / t^2 with G1 = 2 c / (c + sqrt(a^2 + (1 - a^2) c^2)): one root, one division.
        const double t = h[j] * h[j] * (a2 - 1.0) + 1.0;
        const double root = std::sqrt(a2 + (1.0 - a2) * c[j] * c[j]);
        const double d = c[j] * kInvPi, l = s_unit[j] * 2.0 * c[j] / ((c[j] + root) * t * t);
        dd[j] += w[j] * d * d, dl[j] += w[j] * d * l, ll[j] += w[j] * l * l;
        db[j] += w[j] * d * b[j], lb[j] += w[j] * l * b[j];
      }
    }
    for (int j = 0; j < kFloatLanes; ++j) {
      const TwoColumnFit fit = NonNegativeTwoColumnFit(dd[j], dl[j], ll[j], db[j], lb[j], bb[j]);
      if (std::isfinite(fit.chi2) && fit.chi2 < best_chi2[j]) {
        best_chi2[j] = fit.chi2;
        out->diffuse_albedo[j] = fit.diffuse, out->specular_albedo[j] = fit.lobe, out->exponent[j] = roughness;
      }
    }
  }
}

}  // namespace

BlinnPhongMaterial BlinnPhongGridStart(int samples, const double* cos_light, const double* cos_half,
                                       const double* observed, const double* weight, double start_albedo,
                                       const BlinnPhongOptions& options) {
  // Lane 0 holds the pixel; the other lanes have no samples.
  std::vector<double> lanes(4 * static_cast<std::size_t>(samples) * kFloatLanes, 0.0);
  double* lane_cos_light = lanes.data();
  double* lane_cos_half = lane_cos_light + samples * kFloatLanes;
  double* lane_observed = lane_cos_half + samples * kFloatLanes;
  double* lane_weight = lane_observed + samples * kFloatLanes;
  for (int k = 0; k < samples; ++k) {
    lane_cos_light[k * kFloatLanes] = cos_light[k], lane_cos_half[k * kFloatLanes] = cos_half[k];
    lane_observed[k * kFloatLanes] = observed[k], lane_weight[k * kFloatLanes] = weight[k];
  }
  alignas(64) double start[kFloatLanes] = {start_albedo};
  LaneMaterial material;
  BlinnPhongGridStartLanes(samples, lane_cos_light, lane_cos_half, lane_observed, lane_weight, start,
                           options.min_exponent, options.max_exponent, &material);
  return {material.diffuse_albedo[0], material.specular_albedo[0], material.exponent[0]};
}

struct LobeLaneFitter::State {
  LanePoint candidate, current, proposal;
  LaneEquations candidate_equations, current_equations;
  double current_cost[kFloatLanes];
  double lambda[kFloatLanes];
  double positive[kFloatLanes], predicted_decrease[kFloatLanes];
  int iterations[kFloatLanes];
  bool restarted[kFloatLanes];  // the start had no finite cost and the lane started again
  double shared_exponent[kFloatLanes];  // > 0: the lane's lobe is held (LobeProblem's)
  int problem[kFloatLanes];  // index into the problems being fitted, -1 for an idle lane
};

LobeLaneFitter::LobeLaneFitter(const std::vector<Eigen::Vector3d>& light_directions, const Eigen::Vector3d& view,
                               const BlinnPhongOptions& options, LaneLobe lobe)
    : LobeLaneFitter(static_cast<int>(light_directions.size()), options, lobe) {
  per_lane_geometry_ = false;
  view_ = view.normalized();
  evaluation_view_ = {static_cast<float>(view_.x()), static_cast<float>(view_.y()), static_cast<float>(view_.z())};
  std::vector<double> towards_light(3 * light_directions.size());
  for (int k = 0; k < lights_; ++k) {
    const Eigen::Vector3d w = light_directions[k].normalized();
    for (int i = 0; i < 3; ++i) towards_light[3 * k + i] = w[i];
  }
  geometry_.resize(6 * light_directions.size());
  BlinnPhongGeometry(lights_, towards_light.data(), view, geometry_.data());
  evaluation_geometry_.assign(geometry_.begin(), geometry_.end());
}

LobeLaneFitter::LobeLaneFitter(int lights, const BlinnPhongOptions& options, LaneLobe lobe)
    : lights_(lights),
      options_(options),
      lobe_(lobe),
      min_shape_(lobe == LaneLobe::kGgx ? kMinGgxRoughness : options.min_exponent),
      max_shape_(lobe == LaneLobe::kGgx ? kMaxGgxRoughness : options.max_exponent),
      evaluation_geometry_(6 * static_cast<std::size_t>(lights) * kFloatLanes, 0.0f),
      evaluation_view_(3 * kFloatLanes, 0.0f),
      per_lane_geometry_(true),
      observed_(static_cast<std::size_t>(lights) * kFloatLanes),
      inverse_sigma_(static_cast<std::size_t>(lights) * kFloatLanes),
      cos_light_(static_cast<std::size_t>(lights) * kFloatLanes),
      cos_half_(static_cast<std::size_t>(lights) * kFloatLanes),
      start_observed_(static_cast<std::size_t>(lights) * kFloatLanes),
      weight_(static_cast<std::size_t>(lights) * kFloatLanes),
      state_(std::make_unique<State>()) {
  std::fill(evaluation_view_.begin() + 2 * kFloatLanes, evaluation_view_.end(), 1.0f);  // +z until a problem's
}

void BlinnPhongGeometry(int lights, const double* towards_light, const Eigen::Vector3d& view, double* geometry) {
  const Eigen::Vector3d towards_camera = view.normalized();
  for (int k = 0; k < lights; ++k) {
    const Eigen::Vector3d w(towards_light[3 * k], towards_light[3 * k + 1], towards_light[3 * k + 2]);
    const Eigen::Vector3d half = solvers::autodiff::NormalizeGuarded(Eigen::Vector3d(w + towards_camera)).direction;
    for (int i = 0; i < 3; ++i) geometry[6 * k + i] = w[i], geometry[6 * k + 3 + i] = half[i];
  }
}

LobeLaneFitter::~LobeLaneFitter() = default;
LobeLaneFitter::LobeLaneFitter(LobeLaneFitter&&) noexcept = default;

void LobeLaneFitter::LoadSamples(int lane, const LobeProblem& problem) {
  for (int k = 0; k < lights_; ++k) {
    observed_[k * kFloatLanes + lane] = static_cast<float>(problem.observed[k]);
    inverse_sigma_[k * kFloatLanes + lane] = static_cast<float>(problem.inverse_sigma[k]);
  }
  if (!per_lane_geometry_) return;
  for (int i = 0; i < 6 * lights_; ++i)
    evaluation_geometry_[i * kFloatLanes + lane] = static_cast<float>(problem.geometry[i]);
  StoreLaneView(problem.view.normalized(), lane, evaluation_view_.data());
}

void LobeLaneFitter::Load(int lane, const LobeProblem& problem, const BlinnPhongMaterial& start) {
  State& s = *state_;
  const Eigen::Vector3d n = problem.start_normal.normalized();
  LoadSamples(lane, problem);
  LanePoint& q = s.candidate;
  const TangentPair<double> t = TangentBasis(n.x(), n.y(), n.z());
  for (int i = 0; i < 3; ++i) q.normal[i][lane] = n[i], q.tangent[0][i][lane] = t.t1[i], q.tangent[1][i][lane] = t.t2[i];
  q.diffuse_albedo[lane] = start.diffuse_albedo;
  q.specular_albedo[lane] = start.specular_albedo;
  q.exponent[lane] = start.exponent;
  s.current_cost[lane] = std::numeric_limits<double>::infinity();  // the start is always taken
  s.lambda[lane] = 1e-3;
  s.iterations[lane] = 0;
  s.restarted[lane] = false;
  s.shared_exponent[lane] = problem.shared_exponent;
}

void LobeLaneFitter::GridStarts(std::span<const LobeProblem> problems) {
  const int count = static_cast<int>(problems.size());
  starts_.resize(count);
  for (int first = 0; first < count; first += kFloatLanes) {
    alignas(64) double start_albedo[kFloatLanes] = {}, normal[3][kFloatLanes];
    for (int j = 0; j < kFloatLanes; ++j) {
      const bool present = first + j < count;
      const Eigen::Vector3d n = present ? problems[first + j].start_normal.normalized() : Eigen::Vector3d::UnitZ();
      for (int i = 0; i < 3; ++i) normal[i][j] = n[i];
      if (present) start_albedo[j] = problems[first + j].start_albedo;
      // Copies through per-lane pointers, apart from the vector loop below.
      for (int k = 0; k < lights_; ++k) {
        const double inverse_sigma = present ? problems[first + j].inverse_sigma[k] : 0.0;
        start_observed_[k * kFloatLanes + j] = present ? problems[first + j].observed[k] : 0.0;
        weight_[k * kFloatLanes + j] = inverse_sigma * inverse_sigma;
      }
    }
    if (per_lane_geometry_) {
      for (int j = 0; j < kFloatLanes; ++j) {
        const double* g = first + j < count ? problems[first + j].geometry : nullptr;
        for (int k = 0; k < lights_; ++k, g += g ? 6 : 0) {
          const Eigen::Vector3d n(normal[0][j], normal[1][j], normal[2][j]);
          cos_light_[k * kFloatLanes + j] = g ? std::max(0.0, g[0] * n.x() + g[1] * n.y() + g[2] * n.z()) : 0.0;
          cos_half_[k * kFloatLanes + j] = g ? std::max(0.0, g[3] * n.x() + g[4] * n.y() + g[5] * n.z()) : 0.0;
        }
      }
    } else {
      for (int k = 0; k < lights_; ++k) {
        const double* g = &geometry_[6 * k];
        double* cos_light = &cos_light_[k * kFloatLanes];
        double* cos_half = &cos_half_[k * kFloatLanes];
#pragma omp simd
        for (int j = 0; j < kFloatLanes; ++j) {
          cos_light[j] = std::max(0.0, g[0] * normal[0][j] + g[1] * normal[1][j] + g[2] * normal[2][j]);
          cos_half[j] = std::max(0.0, g[3] * normal[0][j] + g[4] * normal[1][j] + g[5] * normal[2][j]);
        }
      }
    }
    if (lobe_ == LaneLobe::kGgx) {
      alignas(64) double cos_view[kFloatLanes];
      for (int j = 0; j < kFloatLanes; ++j) {
        Eigen::Vector3d v = view_;
        if (per_lane_geometry_)
          v = first + j < count ? problems[first + j].view.normalized() : Eigen::Vector3d::UnitZ();
        cos_view[j] = v.x() * normal[0][j] + v.y() * normal[1][j] + v.z() * normal[2][j];
      }
      LaneMaterial material;
      GgxGridStartLanes(lights_, cos_light_.data(), cos_half_.data(), cos_view, start_observed_.data(), weight_.data(),
                        start_albedo, &material);
      for (int j = 0; j < kFloatLanes && first + j < count; ++j)
        starts_[first + j] = {material.diffuse_albedo[j], material.specular_albedo[j], material.exponent[j]};
      continue;
    }
    // Problems with a shared lobe start from it, the others from the grid
    // (which overwrites its inputs, so it goes second).
    alignas(64) double shared_specular[kFloatLanes], shared_exponent[kFloatLanes];
    bool any_shared = false, any_free = false;
    for (int j = 0; j < kFloatLanes; ++j) {
      const bool present = first + j < count;
      shared_specular[j] = present ? problems[first + j].shared_specular_albedo : 0.0;
      shared_exponent[j] = present ? problems[first + j].shared_exponent : 0.0;
      (shared_exponent[j] > 0.0 ? any_shared : any_free) = true;
    }
    LaneMaterial shared, material;
    if (any_shared)
      BlinnPhongSharedStartLanes(lights_, cos_light_.data(), cos_half_.data(), start_observed_.data(), weight_.data(),
                                 start_albedo, shared_specular, shared_exponent, &shared);
    if (any_free)
      BlinnPhongGridStartLanes(lights_, cos_light_.data(), cos_half_.data(), start_observed_.data(), weight_.data(),
                               start_albedo, options_.min_exponent, options_.max_exponent, &material);
    for (int j = 0; j < kFloatLanes && first + j < count; ++j) {
      const LaneMaterial& from = shared_exponent[j] > 0.0 ? shared : material;
      starts_[first + j] = {from.diffuse_albedo[j], from.specular_albedo[j], from.exponent[j]};
    }
  }
}

void LobeLaneFitter::Fit(std::span<const LobeProblem> problems, std::span<LobeSolution> solutions) {
  State& s = *state_;
  const int count = static_cast<int>(problems.size());
  GridStarts(problems);
  // An idle lane evaluates a harmless point with no samples.
  auto idle = [&](int lane) {
    for (int k = 0; k < lights_; ++k) observed_[k * kFloatLanes + lane] = inverse_sigma_[k * kFloatLanes + lane] = 0.0f;
    const TangentPair<double> t = TangentBasis(0.0, 0.0, 1.0);
    for (int i = 0; i < 3; ++i) {
      s.candidate.normal[i][lane] = i == 2 ? 1.0 : 0.0;
      s.candidate.tangent[0][i][lane] = t.t1[i], s.candidate.tangent[1][i][lane] = t.t2[i];
    }
    s.candidate.diffuse_albedo[lane] = s.candidate.specular_albedo[lane] = 0.0;
    s.candidate.exponent[lane] = min_shape_;
    if (per_lane_geometry_) StoreLaneView(Eigen::Vector3d::UnitZ(), lane, evaluation_view_.data());
  };
  LaneQueue queue(count, kFloatLanes);
  // A loaded problem's start is the lane's next candidate.
  auto load = [&](int lane, int index) { Load(lane, problems[index], starts_[index]); };
  auto refill = [&](int lane) { queue.Refill(lane, s.problem, load, idle); };
  for (int lane = 0; lane < kFloatLanes; ++lane) refill(lane);
  auto finish = [&](int lane) {
    LobeSolution& out = solutions[s.problem[lane]];
    out.ok = std::isfinite(s.current_cost[lane]);
    out.normal = Eigen::Vector3d(s.current.normal[0][lane], s.current.normal[1][lane], s.current.normal[2][lane]);
    out.diffuse_albedo = s.current.diffuse_albedo[lane];
    out.specular_albedo = s.current.specular_albedo[lane];
    out.exponent = s.current.exponent[lane];
    out.chi2 = s.current_cost[lane];
    out.iterations = s.iterations[lane];
    refill(lane);
  };
  // Changes of the cost below what the float evaluation resolves are noise.
  const double tolerance = std::max(options_.relative_tolerance, kEvaluationPrecision);
  bool stepping[kFloatLanes];  // lanes whose next candidate is a step from their current point
  while (queue.busy() > 0) {
    EvaluateLanes(lobe_, per_lane_geometry_, s.candidate, lights_, evaluation_geometry_.data(), evaluation_view_.data(),
                  observed_.data(), inverse_sigma_.data(), &s.candidate_equations);
    HoldSharedLobes(s.shared_exponent, &s.candidate_equations);
    for (int lane = 0; lane < kFloatLanes; ++lane) {
      stepping[lane] = false;
      if (s.problem[lane] < 0) continue;
      const double cost = s.candidate_equations.cost[lane];
      const bool at_start = std::isinf(s.current_cost[lane]);
      bool done = false;
      if (cost < s.current_cost[lane]) {
        const double decrease = (s.current_cost[lane] - cost) / std::max(s.current_cost[lane], 1e-300);
        CopyLane(s.candidate, lane, &s.current);
        s.current_equations.cost[lane] = cost;
        for (int e = 0; e < kHessianEntries; ++e) s.current_equations.hessian[e][lane] = s.candidate_equations.hessian[e][lane];
        for (int e = 0; e < kParameters; ++e) s.current_equations.gradient[e][lane] = s.candidate_equations.gradient[e][lane];
        s.current_cost[lane] = cost;
        if (!at_start) {
          ++s.iterations[lane];
          s.lambda[lane] = std::max(s.lambda[lane] / 3.0, 1e-12);
          // A step that lowers chi-square by less than this fraction changes
          // the normal by far less than the noise does: stop there.
          done = decrease <= tolerance || s.iterations[lane] >= options_.max_iterations;
        }
      } else if (at_start) {
        // The start does not evaluate: once more from the diffuse start with
        // no lobe, which evaluates wherever the samples are finite.
        done = s.restarted[lane];
        if (!done) {
          s.restarted[lane] = true;
          s.candidate.diffuse_albedo[lane] = problems[s.problem[lane]].start_albedo;
          if (!(s.shared_exponent[lane] > 0.0)) {  // a shared lobe stays
            s.candidate.specular_albedo[lane] = 0.0;
            s.candidate.exponent[lane] = min_shape_;
          }
          continue;  // stepping stays false: the candidate is evaluated as it is
        }
      } else {
        s.lambda[lane] *= 4.0;
        // Stuck, or the step's change of the cost is below what the float
        // evaluation resolves: the fit is at its minimum to that precision.
        done = s.lambda[lane] >= 1e12 || cost - s.current_cost[lane] <= tolerance * s.current_cost[lane];
      }
      if (done) {
        finish(lane);
      } else {
        stepping[lane] = true;
      }
    }
    // The next candidates, all lanes at once; a lane whose damped system is
    // not positive definite raises its damping and all go round again.
    ProposeWhilePositiveDefinite<kFloatLanes>(
        stepping, s.lambda, s.positive,
        [&] {
          ProposeLanes(s.current, s.current_equations, s.lambda, min_shape_, max_shape_, &s.proposal, s.positive,
                       s.predicted_decrease);
        },
        finish);
    for (int lane = 0; lane < kFloatLanes; ++lane) {
      if (!stepping[lane]) continue;
      // Converged when even the linearised model promises less than the
      // tolerance: otherwise rounding at the minimum rejects step after step
      // while the damping climbs to its limit.
      if (!(s.predicted_decrease[lane] > tolerance * s.current_cost[lane])) {
        finish(lane);
        continue;
      }
      CopyLane(s.proposal, lane, &s.candidate);
    }
  }
}

LobeLaneFitter::Linearization LobeLaneFitter::Linearize(const LobeProblem& problem,
                                                                   const Eigen::Vector3d& normal,
                                                                   double diffuse_albedo, double specular_albedo,
                                                                   double exponent) {
  std::fill(inverse_sigma_.begin(), inverse_sigma_.end(), 0.0f);
  std::fill(observed_.begin(), observed_.end(), 0.0f);
  LanePoint point{};
  for (int lane = 0; lane < kFloatLanes; ++lane) {
    const Eigen::Vector3d n = normal.normalized();
    const TangentPair<double> t = TangentBasis(n.x(), n.y(), n.z());
    for (int i = 0; i < 3; ++i)
      point.normal[i][lane] = n[i], point.tangent[0][i][lane] = t.t1[i], point.tangent[1][i][lane] = t.t2[i];
    point.diffuse_albedo[lane] = diffuse_albedo;
    point.specular_albedo[lane] = specular_albedo;
    point.exponent[lane] = exponent;
  }
  LoadSamples(0, problem);
  LaneEquations equations;
  EvaluateLanes(lobe_, per_lane_geometry_, point, lights_, evaluation_geometry_.data(), evaluation_view_.data(),
                observed_.data(), inverse_sigma_.data(), &equations);
  Linearization out;
  out.cost = equations.cost[0];
  int entry = 0;
  for (int row = 0; row < kParameters; ++row) {
    out.gradient[row] = equations.gradient[row][0];
    for (int col = row; col < kParameters; ++col) out.hessian(row, col) = out.hessian(col, row) = equations.hessian[entry++][0];
  }
  for (int t = 0; t < 2; ++t) out.tangent[t] = Eigen::Vector3d(point.tangent[t][0][0], point.tangent[t][1][0], point.tangent[t][2][0]);
  return out;
}

}  // namespace photorig::solvers::ps::internal
