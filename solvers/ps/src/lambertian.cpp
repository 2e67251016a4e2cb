#include "photorig/solvers/ps/lambertian.h"
#include "lambertian_tiles.h"
#include "kernels/lane_math.h"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <immintrin.h>
#include <omp.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>

namespace photorig::solvers::ps {
namespace {

using internal::SubsetKernel;

constexpr int kMaxLights = 65535;  // NormalMap::usable_lights is 16-bit
constexpr int kTilePixels = 1024;  // 4 KB per accumulator row: stays in L1 across all K planes
// Granularity at which a tile decides whether pixels need their own subsets
// (and skips what the mask leaves out): small enough that a dome-lit object's
// rim of attached shadows does not drag its fully lit interior along.
constexpr int kChunkPixels = 64;
// The subset kernels' intrinsics look up what groups of lights add to the
// normal equations (TileConstants::group_terms) by which of them are usable,
// one register of terms per quantity: groups of four lights (16 patterns)
// with AVX-512, of three (8 patterns) with AVX2.
constexpr int kSubsetGroup = 4;
constexpr int kGroupPatterns = 1 << kSubsetGroup;
constexpr int kSubsetGroupAvx2 = 3;
constexpr int kGroupPatternsAvx2 = 1 << kSubsetGroupAvx2;
constexpr int kGroupQuantities = 8;  // G_S's six entries, the usable count, sum 1 / s^2

// Pseudo-inverse of the full light matrix, with 1/s_k folded in:
// x = sum_k weights(:, k) * (I_k - D).
struct GlobalSolver {
  Eigen::Matrix<float, 3, Eigen::Dynamic> weights;
  double condition_number = std::numeric_limits<double>::infinity();
};

GlobalSolver BuildGlobalSolver(const PhotometricStack& stack) {
  const int k = stack.light_count();
  GlobalSolver solver;
  solver.weights.setZero(3, k);
  Eigen::MatrixXd a(k, 3);
  for (int r = 0; r < k; ++r) a.row(r) = stack.light_directions[r].transpose();
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::Vector3d s = svd.singularValues();
  solver.condition_number = s(2) > 0.0 ? s(0) / s(2) : std::numeric_limits<double>::infinity();
  if (!std::isfinite(solver.condition_number)) return solver;
  const Eigen::MatrixXd pinv =
      svd.matrixV() * s.cwiseInverse().asDiagonal() * svd.matrixU().transpose();  // 3 x k
  for (int r = 0; r < k; ++r) solver.weights.col(r) = (pinv.col(r) / stack.light_scales[r]).cast<float>();
  return solver;
}

// Confidence from the residual: expected / observed residual variance when the
// noise is known (1 = explained down to the noise), else the coefficient of
// determination 1 - RSS / sum(b^2). An exactly determined fit (3 usable
// samples) has no residual to judge it by: 0, untested.
float Confidence(double rss, double expected_rss, double sum_b2, int usable) {
  if (usable <= 3) return 0.0f;
  if (!(rss > 0.0)) return 1.0f;
  if (expected_rss > 0.0) return static_cast<float>(std::min(1.0, expected_rss / rss));
  return static_cast<float>(std::clamp(1.0 - rss / std::max(sum_b2, 1e-300), 0.0, 1.0));
}

// Writes a solved pixel; false when x = 0 (all usable samples were zero after
// dark subtraction, so no direction exists) and nothing was written.
bool WriteSolution(int pixel, float x0, float x1, float x2, float confidence, NormalMap* out) {
  const float length = std::sqrt(x0 * x0 + x1 * x1 + x2 * x2);
  if (!(length > 0.0f)) return false;
  out->normals.ptr<cv::Vec3f>()[pixel] = cv::Vec3f(x0 / length, x1 / length, x2 / length);
  out->albedo.ptr<float>()[pixel] = static_cast<float>(M_PI) * length;
  out->flags.ptr<std::uint8_t>()[pixel] = static_cast<std::uint8_t>(PixelFlag::kSolved);
  out->model.ptr<std::uint8_t>()[pixel] = static_cast<std::uint8_t>(PixelModel::kLambertian);
  out->confidence.ptr<float>()[pixel] = confidence;
  return true;
}

// Marks a pixel unsolved: NaN normal and albedo, no model, zero confidence.
void WriteUnsolved(int pixel, PixelFlag flag, NormalMap* out) {
  out->normals.ptr<cv::Vec3f>()[pixel] = cv::Vec3f::all(std::numeric_limits<float>::quiet_NaN());
  out->albedo.ptr<float>()[pixel] = std::numeric_limits<float>::quiet_NaN();
  out->flags.ptr<std::uint8_t>()[pixel] = static_cast<std::uint8_t>(flag);
  out->model.ptr<std::uint8_t>()[pixel] = static_cast<std::uint8_t>(PixelModel::kNone);
  out->confidence.ptr<float>()[pixel] = 0.0f;
}

// What the per-tile kernels need from the solve's setup. Per-light arrays
// are float (the kernels' precision) and indexed by light.
struct TileConstants {
  const float* const* planes = nullptr;  // K planes
  int lights = 0;
  const float* weights = nullptr;         // 3 x K, row-major: the pseudo-inverse with 1/s_k folded in
  const float* inverse_scale2 = nullptr;  // 1 / s_k^2
  const float* inverse_scale = nullptr;   // 1 / s_k
  const float* direction[3] = {};         // w_k: x, y, z
  // What a group of four lights (4 g .. 4 g + 3) adds to G_S (xx, yy, zz, xy,
  // xz, yz), to the usable count and to sum 1 / s^2, for each of the 16
  // patterns of which of them are usable (bit j: light 4 g + j), as
  // [group][quantity][pattern]: a quantity's 16 patterns fill one AVX-512
  // register, so one permute looks up all sixteen pixels' terms.
  const float* group_terms = nullptr;
  // The same for groups of three lights (3 g .. 3 g + 2) and their 8
  // patterns, one AVX2 register per quantity.
  const float* group_terms_avx2 = nullptr;
  // Per light, w_k's x, y, z and 1 / s_k, each repeated over an AVX2
  // register's eight lanes ([light][quantity][lane]): the AVX2 kernel's
  // multiply-adds read them as memory operands instead of broadcasting them.
  const float* light_lanes_avx2 = nullptr;
  std::array<double, 3> dark_weight{};    // row sums of weights
  std::array<double, 6> gram{};           // G = A^T A: xx, yy, zz, xy, xz, yz
  double sum_inverse_scale2 = 0.0;
  double read_variance = 0.0, shot_gain = 0.0;
  float shadow = 0.0f, saturation = 0.0f;
  // Bound on |G_S|_F^2 |G_S^-1|_F^2 below which a subset is certainly well
  // conditioned: the Frobenius condition number bounds the spectral one.
  float max_frobenius_condition2 = 0.0f;
};

// Per-pixel sums over all K samples of one tile (the L2 path); 8 rows of 4 KB stay in L1.
struct TileSums {
  alignas(64) float x0[kTilePixels], x1[kTilePixels], x2[kTilePixels];
  alignas(64) float q1[kTilePixels], q2[kTilePixels];  // sum I/s^2, sum I^2/s^2
  alignas(64) float usable[kTilePixels];                // count of usable samples (exact in float)
  alignas(64) float dark[kTilePixels];
  alignas(64) float threshold[kTilePixels];             // a sample is usable when threshold < I < saturation
};

// One tile's answer before it is written out: x = rho n, the confidence, the
// usable-sample count and whether the float kernel could vouch for the
// conditioning of the pixel's light subset (else the exact check decides).
struct TileSolution {
  alignas(64) float x0[kTilePixels], x1[kTilePixels], x2[kTilePixels];
  alignas(64) float confidence[kTilePixels];
  alignas(64) float usable[kTilePixels];
  alignas(64) float certainly_conditioned[kTilePixels];  // 1 or 0
};

// x = W I, sum I/s^2, sum I^2/s^2 and the usable-sample count of pixels
// [first, end) of the tile at `begin`, in one pass over their K planes.
// Planes are taken four at a time so the accumulators are loaded and stored
// once per four samples.
//
// The body runs sixteen pixels at a time with a fixed trip count, the sums
// addressed from the one TileSums and the group's twenty weights from one
// local block: with a variable-length inner loop and a pointer per row, GCC
// spilled the rows' addresses and recomputed them for every sixteen pixels
// (as many instructions as the arithmetic itself).
PHOTORIG_PS_MULTIVERSION
void AccumulateTile(const TileConstants& c, int begin, int first, int end, TileSums* t) {
  constexpr int kStep = 16;
  const int k = c.lights;
  const float* w0 = c.weights;
  const float* w1 = c.weights + k;
  const float* w2 = c.weights + 2 * k;
  const float* u = c.inverse_scale2;
  const float saturation = c.saturation;
#pragma omp simd
  for (int i = first; i < end; ++i) {
    t->threshold[i] = t->dark[i] + c.shadow;
    t->x0[i] = t->x1[i] = t->x2[i] = t->q1[i] = t->q2[i] = t->usable[i] = 0.0f;
  }
  // The sums of one group of four planes over pixels [from, to): the planes
  // point at the tile's pixel 0, as the sums' rows do.
  struct Group {
    alignas(64) float w0[4], w1[4], w2[4], u[4];
  };
  auto add_group = [&](const Group& g, const float* __restrict a, const float* __restrict b,
                       const float* __restrict e, const float* __restrict f, int from, int to) {
#pragma omp simd
    for (int i = from; i < to; ++i) {
      const float va = a[i], vb = b[i], ve = e[i], vf = f[i];
      t->x0[i] += g.w0[0] * va + g.w0[1] * vb + g.w0[2] * ve + g.w0[3] * vf;
      t->x1[i] += g.w1[0] * va + g.w1[1] * vb + g.w1[2] * ve + g.w1[3] * vf;
      t->x2[i] += g.w2[0] * va + g.w2[1] * vb + g.w2[2] * ve + g.w2[3] * vf;
      t->q1[i] += g.u[0] * va + g.u[1] * vb + g.u[2] * ve + g.u[3] * vf;
      t->q2[i] += g.u[0] * va * va + g.u[1] * vb * vb + g.u[2] * ve * ve + g.u[3] * vf * vf;
      const float ti = t->threshold[i];
      t->usable[i] += ((va > ti) & (va < saturation) ? 1.0f : 0.0f) + ((vb > ti) & (vb < saturation) ? 1.0f : 0.0f) +
                      ((ve > ti) & (ve < saturation) ? 1.0f : 0.0f) + ((vf > ti) & (vf < saturation) ? 1.0f : 0.0f);
    }
  };
  int l = 0;
  for (; l + 4 <= k; l += 4) {
    Group g;
    for (int j = 0; j < 4; ++j) g.w0[j] = w0[l + j], g.w1[j] = w1[l + j], g.w2[j] = w2[l + j], g.u[j] = u[l + j];
    const float* a = c.planes[l] + begin;
    const float* b = c.planes[l + 1] + begin;
    const float* e = c.planes[l + 2] + begin;
    const float* f = c.planes[l + 3] + begin;
    // The planes two groups on are fetched meanwhile, a cache line of each
    // per 16 pixels: a tile reads 4 KB of each plane, and the hardware
    // prefetchers stop at every 4 KB page, so each plane's run starts cold.
    const int ahead = std::min(l + 8, k - 4);
    const float* pa = c.planes[ahead] + begin;
    const float* pb = c.planes[ahead + 1] + begin;
    const float* pe = c.planes[ahead + 2] + begin;
    const float* pf = c.planes[ahead + 3] + begin;
    int i = first;
    for (; i + kStep <= end; i += kStep) {
      __builtin_prefetch(pa + i);
      __builtin_prefetch(pb + i);
      __builtin_prefetch(pe + i);
      __builtin_prefetch(pf + i);
      add_group(g, a, b, e, f, i, i + kStep);
    }
    add_group(g, a, b, e, f, i, end);
  }
  for (; l < k; ++l) {
    const float* __restrict a = c.planes[l] + begin;
#pragma omp simd
    for (int i = first; i < end; ++i) {
      const float v = a[i];
      t->x0[i] += w0[l] * v;
      t->x1[i] += w1[l] * v;
      t->x2[i] += w2[l] * v;
      t->q1[i] += u[l] * v;
      t->q2[i] += u[l] * v * v;
      t->usable[i] += (v > t->threshold[i]) & (v < saturation) ? 1.0f : 0.0f;
    }
  }
}

// The L2 answer of pixels [first, end) of the tile from their sums: x with
// the dark frame folded out, confidence from RSS = sum b^2 - x^T G x.
PHOTORIG_PS_MULTIVERSION
void SolveLitTile(const TileConstants& c, int first, int end, const TileSums& t, TileSolution* s) {
  const double k = c.lights;
  const double dof_fraction = (k - 3.0) / k;
#pragma omp simd
  for (int i = first; i < end; ++i) {
    const double d = t.dark[i];
    const double x = t.x0[i] - c.dark_weight[0] * d;
    const double y = t.x1[i] - c.dark_weight[1] * d;
    const double z = t.x2[i] - c.dark_weight[2] * d;
    const double sum_b2 = t.q2[i] - 2.0 * d * t.q1[i] + d * d * c.sum_inverse_scale2;
    const double xgx = c.gram[0] * x * x + c.gram[1] * y * y + c.gram[2] * z * z +
                       2.0 * (c.gram[3] * x * y + c.gram[4] * x * z + c.gram[5] * y * z);
    const double rss = std::max(0.0, sum_b2 - xgx);
    const double signal = std::max(0.0, t.q1[i] - d * c.sum_inverse_scale2);
    const double expected = (c.read_variance * c.sum_inverse_scale2 + c.shot_gain * signal) * dof_fraction;
    // Confidence(): expected / observed residual variance, or R^2 without a
    // noise model. Everything is computed on every lane and then selected, so
    // the loop vectorises.
    const double known = std::min(1.0, expected / rss);
    const double r2 = std::clamp(1.0 - rss / std::max(sum_b2, 1e-300), 0.0, 1.0);
    const double tested = rss > 0.0 ? (expected > 0.0 ? known : r2) : 1.0;
    s->confidence[i] = static_cast<float>(k > 3.0 ? tested : 0.0);
    s->x0[i] = static_cast<float>(x);
    s->x1[i] = static_cast<float>(y);
    s->x2[i] = static_cast<float>(z);
    s->usable[i] = t.usable[i];
    s->certainly_conditioned[i] = 1.0f;  // the full light set was checked once for all pixels
  }
}

// Per-pixel sums over the usable samples of a block of a tile: the normal
// equations G_S x = A_S^T b_S and what the residual test needs. A block's
// 14 rows (14 KB) stay in L1 while its samples stream past.
constexpr int kBlockPixels = 256;
// Residuals from the normal equations' sums are trusted to this fraction of
// their value (see SolveSubsetTile); the factor is three sums' statistical
// rounding, 3 sqrt(n) u, with a factor two to spare.
constexpr double kResidualTolerance = 0.1;
constexpr double kRoundingPerSqrtSample = 6.0 / (1 << 24);
struct SubsetBlock {
  alignas(64) float g[6][kBlockPixels];  // G_S: xx, yy, zz, xy, xz, yz
  alignas(64) float r[3][kBlockPixels];  // A_S^T b_S
  alignas(64) float usable[kBlockPixels], u[kBlockPixels], signal[kBlockPixels], b2[kBlockPixels];
  alignas(64) float rss[kBlockPixels];
};

// The constants of four consecutive lights for one sweep over a block, so
// the accumulators are loaded and stored once per four samples. Missing
// lights of the last group repeat light 0 with weight 0 (present = 0).
struct LightGroup {
  static constexpr int kSize = 4;
  const float* planes[kSize];  // each at pixel `offset`
  float wx[kSize], wy[kSize], wz[kSize], inverse_scale[kSize], u[kSize], present[kSize];
};

// Inlined, so the group stays a local the compiler can keep in registers.
__attribute__((always_inline)) inline LightGroup GroupAt(const TileConstants& c, int first, int offset) {
  LightGroup group;
  for (int j = 0; j < LightGroup::kSize; ++j) {
    const int l = first + j < c.lights ? first + j : 0;
    group.planes[j] = c.planes[l] + offset;
    group.wx[j] = c.direction[0][l];
    group.wy[j] = c.direction[1][l];
    group.wz[j] = c.direction[2][l];
    group.present[j] = first + j < c.lights ? 1.0f : 0.0f;
    group.inverse_scale[j] = group.present[j] * c.inverse_scale[l];
    group.u[j] = group.present[j] * c.inverse_scale2[l];
  }
  return group;
}

// The sums of one block's normal equations (see SubsetBlock) over the usable
// samples of pixels [offset, offset + count), four lights per sweep.
PHOTORIG_PS_MULTIVERSION
void AccumulateSubsetBlock(const TileConstants& c, int offset, int count, const float* __restrict d, SubsetBlock* a) {
  constexpr int kGroup = LightGroup::kSize;
  const int k = c.lights;
  const float saturation = c.saturation;
  for (auto* row : {a->g[0], a->g[1], a->g[2], a->g[3], a->g[4], a->g[5], a->r[0], a->r[1], a->r[2], a->usable, a->u,
                    a->signal, a->b2})
    std::fill(row, row + count, 0.0f);
  for (int first = 0; first < k; first += kGroup) {
    const LightGroup group = GroupAt(c, first, offset);
    const auto& planes = group.planes;
    const auto &wx = group.wx, &wy = group.wy, &wz = group.wz, &inverse_scale = group.inverse_scale;
    const auto &u = group.u, &present = group.present;
    float wxx[kGroup], wyy[kGroup], wzz[kGroup], wxy[kGroup], wxz[kGroup], wyz[kGroup];
    for (int j = 0; j < kGroup; ++j) {
      wxx[j] = wx[j] * wx[j], wyy[j] = wy[j] * wy[j], wzz[j] = wz[j] * wz[j];
      wxy[j] = wx[j] * wy[j], wxz[j] = wx[j] * wz[j], wyz[j] = wy[j] * wz[j];
    }
#pragma omp simd
    for (int i = 0; i < count; ++i) {
      float gxx = a->g[0][i], gyy = a->g[1][i], gzz = a->g[2][i], gxy = a->g[3][i], gxz = a->g[4][i], gyz = a->g[5][i];
      float rx = a->r[0][i], ry = a->r[1][i], rz = a->r[2][i];
      float usable = a->usable[i], su = a->u[i], signal_sum = a->signal[i], b2 = a->b2[i];
      const float threshold = d[i] + c.shadow;
      for (int j = 0; j < kGroup; ++j) {
        const float v = planes[j][i];
        // Conditional sums rather than products with a 0/1 weight: with
        // AVX-512 each is one merge-masked add.
        if ((v > threshold) & (v < saturation) & (present[j] != 0.0f)) {
          const float signal = v - d[i];
          const float b = signal * inverse_scale[j];
          gxx += wxx[j];
          gyy += wyy[j];
          gzz += wzz[j];
          gxy += wxy[j];
          gxz += wxz[j];
          gyz += wyz[j];
          rx += wx[j] * b;
          ry += wy[j] * b;
          rz += wz[j] * b;
          usable += 1.0f;
          su += u[j];
          signal_sum += signal * u[j];
          b2 += b * b;
        }
      }
      a->g[0][i] = gxx, a->g[1][i] = gyy, a->g[2][i] = gzz, a->g[3][i] = gxy, a->g[4][i] = gxz, a->g[5][i] = gyz;
      a->r[0][i] = rx, a->r[1][i] = ry, a->r[2][i] = rz;
      a->usable[i] = usable, a->u[i] = su, a->signal[i] = signal_sum, a->b2[i] = b2;
    }
  }
}

// The same sums with AVX-512 intrinsics, sixteen pixels at a time with the
// thirteen sums in registers (GCC's code for the loop above keeps them in
// memory and copies registers around each merge-masked add). The lights come
// in sweeps of kSweepLights over the whole block, the sums' rows (13 KB) in
// L1 between sweeps: a sweep reads that many planes' runs in order, which
// the prefetchers keep up with, where one sweep through all K planes per
// sixteen pixels left the loads waiting on K streams at once (with 96
// lights a shadowed 1 MP stack took 1.4x as long). The eight sums that
// depend only on which lights are usable (G_S, the count, sum 1 / s^2) are
// looked up per group of four lights by each pixel's usable pattern
// (group_terms) instead of summed light by light: one permute and one add
// per sum and group where there were four masked adds. Each light's line
// kPrefetchLines iterations on is prefetched into L2. Each pixel's sums add
// their terms in the order AccumulateSubsetBlock's do.
//
// Sweeps of 16-32 lights ran alike; 4 (the sums through L1 for every
// group) and all K were slower. 32: a load and a store of the thirteen sums
// per sixteen pixels cost under one instruction per light.
constexpr int kSweepLights = 32, kPrefetchLines = 8;
static_assert(kSweepLights % kSubsetGroup == 0);
__attribute__((target("avx512f"))) void AccumulateSubsetBlockAvx512(const TileConstants& c, int offset, int count,
                                                                    const float* __restrict d, SubsetBlock* a) {
  constexpr int kLanes = 16;
  static_assert(kBlockPixels % kLanes == 0 && kGroupPatterns == kLanes);
  float* const pattern_rows[kGroupQuantities] = {a->g[0], a->g[1], a->g[2], a->g[3], a->g[4], a->g[5], a->usable, a->u};
  float* const sum_rows[5] = {a->r[0], a->r[1], a->r[2], a->signal, a->b2};
  const int padded = (count + kLanes - 1) / kLanes * kLanes;  // rows hold kBlockPixels
  for (float* row : pattern_rows) std::fill(row, row + padded, 0.0f);
  for (float* row : sum_rows) std::fill(row, row + padded, 0.0f);
  const __m512 saturation = _mm512_set1_ps(c.saturation), shadow = _mm512_set1_ps(c.shadow);
  for (int sweep = 0; sweep < c.lights; sweep += kSweepLights) {
    const int sweep_end = std::min(sweep + kSweepLights, c.lights);
    for (int i = 0; i < count; i += kLanes) {
      const __mmask16 lanes = count - i >= kLanes ? __mmask16(0xFFFF) : __mmask16((1u << (count - i)) - 1u);
      const __m512 dark = _mm512_maskz_loadu_ps(lanes, d + i);
      const __m512 threshold = _mm512_add_ps(dark, shadow);
      __m512 rx = _mm512_load_ps(sum_rows[0] + i), ry = _mm512_load_ps(sum_rows[1] + i);
      __m512 rz = _mm512_load_ps(sum_rows[2] + i), signal_sum = _mm512_load_ps(sum_rows[3] + i);
      __m512 b2 = _mm512_load_ps(sum_rows[4] + i);
      __m512 pattern_sums[kGroupQuantities];
      for (int q = 0; q < kGroupQuantities; ++q) pattern_sums[q] = _mm512_load_ps(pattern_rows[q] + i);
      for (int first = sweep; first < sweep_end; first += kSubsetGroup) {
        __m512i pattern = _mm512_setzero_si512();
        const int end = std::min(first + kSubsetGroup, c.lights);
        for (int j = first; j < end; ++j) {
          const float* samples = c.planes[j] + offset + i;
          _mm_prefetch(reinterpret_cast<const char*>(samples + kPrefetchLines * kLanes), _MM_HINT_T1);
          const __m512 v = _mm512_maskz_loadu_ps(lanes, samples);
          const __mmask16 usable = _mm512_mask_cmp_ps_mask(
              _mm512_mask_cmp_ps_mask(lanes, v, threshold, _CMP_GT_OQ), v, saturation, _CMP_LT_OQ);
          const __m512 signal = _mm512_sub_ps(v, dark);
          const __m512 b = _mm512_mul_ps(signal, _mm512_set1_ps(c.inverse_scale[j]));
          pattern = _mm512_mask_or_epi32(pattern, usable, pattern, _mm512_set1_epi32(1 << (j - first)));
          rx = _mm512_mask3_fmadd_ps(_mm512_set1_ps(c.direction[0][j]), b, rx, usable);
          ry = _mm512_mask3_fmadd_ps(_mm512_set1_ps(c.direction[1][j]), b, ry, usable);
          rz = _mm512_mask3_fmadd_ps(_mm512_set1_ps(c.direction[2][j]), b, rz, usable);
          signal_sum = _mm512_mask3_fmadd_ps(signal, _mm512_set1_ps(c.inverse_scale2[j]), signal_sum, usable);
          b2 = _mm512_mask3_fmadd_ps(b, b, b2, usable);
        }
        const float* terms = c.group_terms + static_cast<std::size_t>(first / kSubsetGroup) * kGroupQuantities * kLanes;
        // The masked form with an all-ones mask: GCC 12 warns about the plain one's undefined source operand.
        for (int q = 0; q < kGroupQuantities; ++q)
          pattern_sums[q] = _mm512_add_ps(
              pattern_sums[q], _mm512_maskz_permutexvar_ps(0xFFFF, pattern, _mm512_loadu_ps(terms + q * kLanes)));
      }
      _mm512_store_ps(sum_rows[0] + i, rx);
      _mm512_store_ps(sum_rows[1] + i, ry);
      _mm512_store_ps(sum_rows[2] + i, rz);
      _mm512_store_ps(sum_rows[3] + i, signal_sum);
      _mm512_store_ps(sum_rows[4] + i, b2);
      for (int q = 0; q < kGroupQuantities; ++q) _mm512_store_ps(pattern_rows[q] + i, pattern_sums[q]);
    }
  }
}

// The same sums with AVX2 and FMA, eight pixels at a time. Without mask
// registers each conditional sum is an AND and an add, and sixteen registers
// cannot hold the thirteen sums with the samples in flight, so a sweep runs
// in two parts per eight pixels: the five sums of the samples themselves
// with the lights' usable pattern in registers (three bits per group of
// three lights, 24 lights to a sweep), then the eight pattern sums, one
// permute and one add per sum and group (group_terms_avx2). GCC's code for
// the portable loop spilled the sums to the stack and blended every one
// (4 cycles a sample on Zen 2, three quarters of a shadowed solve). Each
// light's direction, 1 / s and pattern bit come from tables as memory
// operands, and the light and group tables are walked by pointer: 21
// instructions a light and eight pixels, where broadcasting them, making
// the bit and indexing the tables took 32.
constexpr int kSweepLightsAvx2 = 24;
static_assert(kSweepLightsAvx2 % kSubsetGroupAvx2 == 0 && kSweepLightsAvx2 <= 32);
// Bit j of the usable pattern in every lane, for the sweep's light j: read as
// a memory operand, where making it took a shift, a move and a broadcast.
constexpr std::array<std::array<std::int32_t, 8>, kSweepLightsAvx2> kSweepBits = [] {
  std::array<std::array<std::int32_t, 8>, kSweepLightsAvx2> bits{};
  for (int j = 0; j < kSweepLightsAvx2; ++j) bits[j].fill(std::int32_t{1} << j);
  return bits;
}();
__attribute__((target("avx2,fma"))) void AccumulateSubsetBlockAvx2(const TileConstants& c, int offset, int count,
                                                                   const float* __restrict d, SubsetBlock* a) {
  constexpr int kLanes = 8;
  static_assert(kBlockPixels % kLanes == 0 && kGroupPatternsAvx2 == kLanes);
  float* const pattern_rows[kGroupQuantities] = {a->g[0], a->g[1], a->g[2], a->g[3], a->g[4], a->g[5], a->usable, a->u};
  float* const sum_rows[5] = {a->r[0], a->r[1], a->r[2], a->signal, a->b2};
  const int padded = (count + kLanes - 1) / kLanes * kLanes;  // rows hold kBlockPixels
  for (float* row : pattern_rows) std::fill(row, row + padded, 0.0f);
  for (float* row : sum_rows) std::fill(row, row + padded, 0.0f);
  const __m256 saturation = _mm256_set1_ps(c.saturation), shadow = _mm256_set1_ps(c.shadow);
  const __m256i lane_index = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  for (int sweep = 0; sweep < c.lights; sweep += kSweepLightsAvx2) {
    const int sweep_end = std::min(sweep + kSweepLightsAvx2, c.lights);
    for (int i = 0; i < count; i += kLanes) {
      // The last eight may reach past the block, and past the image: loaded masked.
      const __m256i lanes = _mm256_cmpgt_epi32(_mm256_set1_epi32(count - i), lane_index);
      const bool whole = count - i >= kLanes;
      const __m256 dark = _mm256_maskload_ps(d + i, lanes);
      const __m256 threshold = _mm256_add_ps(dark, shadow);
      __m256 rx = _mm256_load_ps(sum_rows[0] + i), ry = _mm256_load_ps(sum_rows[1] + i);
      __m256 rz = _mm256_load_ps(sum_rows[2] + i), signal_sum = _mm256_load_ps(sum_rows[3] + i);
      __m256 b2 = _mm256_load_ps(sum_rows[4] + i);
      __m256i pattern = _mm256_setzero_si256();  // bit j: light sweep + j usable
      const float* light = c.light_lanes_avx2 + static_cast<std::size_t>(sweep) * 4 * kLanes;
      const std::int32_t* bit = kSweepBits[0].data();
      for (int j = sweep; j < sweep_end; ++j, light += 4 * kLanes, bit += kLanes) {
        const float* samples = c.planes[j] + offset + i;
        _mm_prefetch(reinterpret_cast<const char*>(samples + kPrefetchLines * kLanes), _MM_HINT_T1);
        const __m256 v = whole ? _mm256_loadu_ps(samples) : _mm256_maskload_ps(samples, lanes);
        // A lane past the block loads 0 as its sample and its dark, and 0 is
        // never above the shadow threshold (>= 0): never usable.
        const __m256 usable =
            _mm256_and_ps(_mm256_cmp_ps(v, threshold, _CMP_GT_OQ), _mm256_cmp_ps(v, saturation, _CMP_LT_OQ));
        const __m256 inverse_scale = _mm256_loadu_ps(light + 3 * kLanes);
        const __m256 b = _mm256_and_ps(usable, _mm256_mul_ps(_mm256_sub_ps(v, dark), inverse_scale));
        pattern = _mm256_or_si256(pattern, _mm256_and_si256(_mm256_castps_si256(usable),
                                                            _mm256_loadu_si256(reinterpret_cast<const __m256i*>(bit))));
        rx = _mm256_fmadd_ps(_mm256_loadu_ps(light), b, rx);
        ry = _mm256_fmadd_ps(_mm256_loadu_ps(light + kLanes), b, ry);
        rz = _mm256_fmadd_ps(_mm256_loadu_ps(light + 2 * kLanes), b, rz);
        signal_sum = _mm256_fmadd_ps(b, inverse_scale, signal_sum);  // (v - dark) / s^2
        b2 = _mm256_fmadd_ps(b, b, b2);
      }
      _mm256_store_ps(sum_rows[0] + i, rx);
      _mm256_store_ps(sum_rows[1] + i, ry);
      _mm256_store_ps(sum_rows[2] + i, rz);
      _mm256_store_ps(sum_rows[3] + i, signal_sum);
      _mm256_store_ps(sum_rows[4] + i, b2);
      __m256 pattern_sums[kGroupQuantities];
      for (int q = 0; q < kGroupQuantities; ++q) pattern_sums[q] = _mm256_load_ps(pattern_rows[q] + i);
      // The sweep's groups' terms follow one another (sweeps start on a group).
      const float* terms =
          c.group_terms_avx2 + static_cast<std::size_t>(sweep / kSubsetGroupAvx2) * kGroupQuantities * kLanes;
      for (int first = sweep; first < sweep_end; first += kSubsetGroupAvx2, terms += kGroupQuantities * kLanes) {
        // vpermps reads an index's low three bits: the group's pattern once shifted down.
        const __m256i group_pattern = _mm256_srli_epi32(pattern, first - sweep);
        for (int q = 0; q < kGroupQuantities; ++q)
          pattern_sums[q] = _mm256_add_ps(
              pattern_sums[q], _mm256_permutevar8x32_ps(_mm256_loadu_ps(terms + q * kLanes), group_pattern));
      }
      for (int q = 0; q < kGroupQuantities; ++q) _mm256_store_ps(pattern_rows[q] + i, pattern_sums[q]);
    }
  }
}

std::atomic<int> chosen_subset_kernel{-1};  // a SubsetKernel; -1: the fastest available

bool CpuSupports(SubsetKernel kernel) {
  static const bool avx512 = (__builtin_cpu_init(), __builtin_cpu_supports("avx512f"));
  static const bool avx2 = (__builtin_cpu_init(), __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"));
  switch (kernel) {
    case SubsetKernel::kAvx512: return avx512;
    case SubsetKernel::kAvx2: return avx2;
    case SubsetKernel::kPortable: return true;
  }
  return false;
}

SubsetKernel ActiveSubsetKernel() {
  const int chosen = chosen_subset_kernel.load(std::memory_order_relaxed);
  if (chosen >= 0) return static_cast<SubsetKernel>(chosen);
  static const SubsetKernel fastest = CpuSupports(SubsetKernel::kAvx512) ? SubsetKernel::kAvx512
                                      : CpuSupports(SubsetKernel::kAvx2) ? SubsetKernel::kAvx2
                                                                         : SubsetKernel::kPortable;
  return fastest;
}

// Least squares on each pixel's usable samples, for pixels [first, end) of a
// tile, block by block: one sweep over a block's K samples sums the normal
// equations, the 3 x 3 systems are solved by their adjugates, and the
// residual comes from the same sums unless float rounding could blur it (then
// a second sweep sums the residuals themselves). A pixel whose samples are
// all usable gets the full set's least squares again.
PHOTORIG_PS_MULTIVERSION
void SolveSubsetTile(const TileConstants& c, int begin, int first, int end, const float* dark, SubsetBlock* a,
                     TileSolution* s) {
  constexpr int kGroup = LightGroup::kSize;
  const int k = c.lights;
  const float saturation = c.saturation;
  const float read_variance = static_cast<float>(c.read_variance), shot_gain = static_cast<float>(c.shot_gain);
  for (int first_pixel = first; first_pixel < end; first_pixel += kBlockPixels) {
    const int count = std::min(kBlockPixels, end - first_pixel);
    const float* __restrict d = dark + first_pixel;
    switch (ActiveSubsetKernel()) {
      case SubsetKernel::kAvx512: AccumulateSubsetBlockAvx512(c, begin + first_pixel, count, d, a); break;
      case SubsetKernel::kAvx2: AccumulateSubsetBlockAvx2(c, begin + first_pixel, count, d, a); break;
      case SubsetKernel::kPortable: AccumulateSubsetBlock(c, begin + first_pixel, count, d, a); break;
    }
    float* __restrict x0 = s->x0 + first_pixel;
    float* __restrict x1 = s->x1 + first_pixel;
    float* __restrict x2 = s->x2 + first_pixel;
    float* __restrict certain = s->certainly_conditioned + first_pixel;
    const float all = static_cast<float>(k);
#pragma omp simd
    for (int i = 0; i < count; ++i) {
      const float gxx = a->g[0][i], gyy = a->g[1][i], gzz = a->g[2][i], gxy = a->g[3][i], gxz = a->g[4][i], gyz = a->g[5][i];
      // Adjugate of the symmetric G_S; G_S^-1 = adj / det.
      const float a00 = gyy * gzz - gyz * gyz, a01 = gxz * gyz - gxy * gzz, a02 = gxy * gyz - gxz * gyy;
      const float a11 = gxx * gzz - gxz * gxz, a12 = gxy * gxz - gxx * gyz, a22 = gxx * gyy - gxy * gxy;
      const float det = gxx * a00 + gxy * a01 + gxz * a02;
      const float inverse_det = det > 0.0f ? 1.0f / det : 0.0f;
      const float rx = a->r[0][i], ry = a->r[1][i], rz = a->r[2][i];
      x0[i] = (a00 * rx + a01 * ry + a02 * rz) * inverse_det;
      x1[i] = (a01 * rx + a11 * ry + a12 * rz) * inverse_det;
      x2[i] = (a02 * rx + a12 * ry + a22 * rz) * inverse_det;
      const float g_norm2 = gxx * gxx + gyy * gyy + gzz * gzz + 2.0f * (gxy * gxy + gxz * gxz + gyz * gyz);
      const float adj_norm2 = a00 * a00 + a11 * a11 + a22 * a22 + 2.0f * (a01 * a01 + a02 * a02 + a12 * a12);
      const float bound = g_norm2 * adj_norm2 * inverse_det * inverse_det;
      // Full-set pixels were checked once for all; where det <= 0 the bound
      // is 0 (inverse_det = 0), so det > 0 is tested on its own.
      certain[i] = (a->usable[i] == all) | ((det > 0.0f) & (bound <= c.max_frobenius_condition2)) ? 1.0f : 0.0f;
    }
    // The residual from the sums, RSS = b^2 - 2 x^T r + x^T G x (stationary
    // in x, so the solve's rounding enters squared). Its own rounding error
    // grows with b^2, not with RSS: statistically about sqrt(n) u b^2 for each
    // of the three float sums of n terms (u = 2^-24). Where that could exceed
    // kResidualTolerance of RSS anywhere in the block (a fit closer than
    // float sums can resolve), a second sweep sums the residuals themselves.
    int exact_needed = 0;
#pragma omp simd reduction(max : exact_needed)
    for (int i = 0; i < count; ++i) {
      const double x = x0[i], y = x1[i], z = x2[i];
      const double gx = a->g[0][i] * x + a->g[3][i] * y + a->g[4][i] * z;
      const double gy = a->g[3][i] * x + a->g[1][i] * y + a->g[5][i] * z;
      const double gz = a->g[4][i] * x + a->g[5][i] * y + a->g[2][i] * z;
      const double xr = x * a->r[0][i] + y * a->r[1][i] + z * a->r[2][i];
      const double rss = std::max(0.0, a->b2[i] - 2.0 * xr + (x * gx + y * gy + z * gz));
      // rounding > tolerance * RSS, compared squared (no square root per pixel).
      const double rounding2 = kRoundingPerSqrtSample * kRoundingPerSqrtSample * a->usable[i] * a->b2[i] * a->b2[i];
      const double tolerated = kResidualTolerance * rss;
      a->rss[i] = static_cast<float>(rss);
      exact_needed = std::max(exact_needed, (a->usable[i] > 3.0f) & (rounding2 > tolerated * tolerated) ? 1 : 0);
    }
    if (exact_needed) {
      std::fill(a->rss, a->rss + count, 0.0f);
      for (int first = 0; first < k; first += kGroup) {
        const LightGroup group = GroupAt(c, first, begin + first_pixel);
        const auto& planes = group.planes;
        const auto &wx = group.wx, &wy = group.wy, &wz = group.wz, &inverse_scale = group.inverse_scale;
        const auto& present = group.present;
#pragma omp simd
        for (int i = 0; i < count; ++i) {
          float rss = a->rss[i];
          const float threshold = d[i] + c.shadow;
          for (int j = 0; j < kGroup; ++j) {
            const float v = planes[j][i];
            const float r = (v - d[i]) * inverse_scale[j] - (wx[j] * x0[i] + wy[j] * x1[i] + wz[j] * x2[i]);
            rss += (v > threshold) & (v < saturation) ? present[j] * r * r : 0.0f;
          }
          a->rss[i] = rss;
        }
      }
    }
    float* __restrict confidence = s->confidence + first_pixel;
    float* __restrict usable_out = s->usable + first_pixel;
#pragma omp simd
    for (int i = 0; i < count; ++i) {
      const float usable = a->usable[i], rss = a->rss[i], b2 = a->b2[i];
      // As Confidence(), with one division: expected / RSS capped at 1, where
      // expected = noise * (n - 3) / n, or else 1 - RSS / b^2 clamped to [0, 1].
      const float noise = (read_variance * a->u[i] + shot_gain * a->signal[i]) * (usable - 3.0f);
      const float rss_times_n = std::max(usable, 1.0f) * rss, b2_floor = std::max(b2, 1e-30f);
      const float numerator = noise > 0.0f ? noise : b2 - rss;
      const float denominator = noise > 0.0f ? rss_times_n : b2_floor;
      const float ratio = std::clamp(numerator / denominator, 0.0f, 1.0f);
      const float tested = rss > 0.0f ? ratio : 1.0f;
      confidence[i] = usable > 3.0f ? tested : 0.0f;
      usable_out[i] = usable;
    }
  }
}

// solve(first, end) for each maximal run [first, end) of consecutive chunks
// of a tile's n pixels for which wanted(chunk_first, chunk_end) holds.
template <typename Wanted, typename Solve>
void ForEachRunOfChunks(int n, Wanted&& wanted, Solve&& solve) {
  int run_first = -1;
  for (int chunk = 0; chunk < n; chunk += kChunkPixels) {
    const bool in_run = wanted(chunk, std::min(n, chunk + kChunkPixels));
    if (in_run && run_first < 0) run_first = chunk;
    if (!in_run && run_first >= 0) {
      solve(run_first, chunk);
      run_first = -1;
    }
  }
  if (run_first >= 0) solve(run_first, n);
}

// A solving thread's working rows, about 70 KB. They live as long as the
// thread (OpenMP keeps its threads between solves), so a solve neither
// allocates them nor faults their pages in again.
struct TileScratch {
  TileSums sums;
  TileSolution solution;
  SubsetBlock block;
};

TileScratch& ThreadTileScratch() {
  thread_local const auto scratch = std::make_unique<TileScratch>();
  return *scratch;
}

// Writes every pixel of the tile from its solution: normal, albedo,
// confidence, usable count, model, zero specular and the flag: outside the
// mask, too few usable samples (or x = 0: no direction exists) or solved.
PHOTORIG_PS_MULTIVERSION
void WriteTile(int begin, int n, const TileSolution& s, const std::uint8_t* mask, NormalMap* out) {
  float* __restrict normals = out->normals.ptr<float>() + 3 * static_cast<std::size_t>(begin);
  float* __restrict albedo = out->albedo.ptr<float>() + begin;
  float* __restrict confidence = out->confidence.ptr<float>() + begin;
  float* __restrict specular = out->specular.ptr<float>() + 2 * static_cast<std::size_t>(begin);
  std::uint8_t* __restrict flags = out->flags.ptr<std::uint8_t>() + begin;
  std::uint8_t* __restrict model = out->model.ptr<std::uint8_t>() + begin;
  std::uint16_t* __restrict usable = out->usable_lights.ptr<std::uint16_t>() + begin;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  // Inside the mask as 1 / 0 floats, so the float loop below stays at full width.
  alignas(64) float inside[kTilePixels];
  for (int i = 0; i < n; ++i) inside[i] = mask == nullptr || mask[begin + i] != 0 ? 1.0f : 0.0f;
#pragma omp simd
  for (int i = 0; i < n; ++i) {
    const float x = s.x0[i], y = s.x1[i], z = s.x2[i];
    const float length = std::sqrt(x * x + y * y + z * z);
    const bool solved = (length > 0.0f) & (inside[i] > 0.0f) & (s.usable[i] >= 3.0f);
    const float inverse = solved ? 1.0f / length : nan;
    normals[3 * i] = x * inverse;
    normals[3 * i + 1] = y * inverse;
    normals[3 * i + 2] = z * inverse;
    albedo[i] = solved ? static_cast<float>(M_PI) * length : nan;
    confidence[i] = solved ? s.confidence[i] : 0.0f;
  }
  // The narrow outputs in a loop of their own: mixed with the float lanes
  // above they would force narrower vectors.
#pragma omp simd
  for (int i = 0; i < n; ++i) {
    const bool solved = albedo[i] > 0.0f;  // false for NaN
    const bool outside = inside[i] == 0.0f;
    flags[i] = static_cast<std::uint8_t>(solved ? PixelFlag::kSolved
                                         : outside ? PixelFlag::kOutsideMask
                                                   : PixelFlag::kTooFewLights);
    model[i] = solved ? static_cast<std::uint8_t>(PixelModel::kLambertian) : std::uint8_t{0};
    usable[i] = outside ? std::uint16_t{0} : static_cast<std::uint16_t>(s.usable[i]);
  }
  std::fill(specular, specular + 2 * n, 0.0f);
}

// Pixels with fewer usable samples than `lights`.
PHOTORIG_PS_MULTIVERSION
int CountPartlyUsable(const float* usable, int n, float lights) {
  int fewer = 0;
#pragma omp simd reduction(+ : fewer)
  for (int i = 0; i < n; ++i) fewer += usable[i] != lights ? 1 : 0;
  return fewer;
}

// Solved pixels whose subset the float kernel could not vouch for.
PHOTORIG_PS_MULTIVERSION
int CountUnverified(const float* certainly_conditioned, const std::uint16_t* usable, int n) {
  int unverified = 0;
#pragma omp simd reduction(+ : unverified)
  for (int i = 0; i < n; ++i) unverified += (certainly_conditioned[i] == 0.0f) & (usable[i] >= 3) ? 1 : 0;
  return unverified;
}

// A written tile's pixels by flag, for the summary.
struct TileCounts {
  int rejected_samples = 0, on_subset = 0, solved = 0, outside_mask = 0, too_few = 0, ill_conditioned = 0;
};

PHOTORIG_PS_MULTIVERSION
TileCounts CountTile(const std::uint8_t* flags, const std::uint16_t* usable, int n, int lights) {
  // int counters of one type, so that GCC vectorises the loop.
  int rejected = 0, subset = 0, solved = 0, outside = 0, too_few = 0, ill = 0;
#pragma omp simd reduction(+ : rejected, subset, solved, outside, too_few, ill)
  for (int i = 0; i < n; ++i) {
    const int flag = flags[i], lit = usable[i];
    const int is_outside = flag == static_cast<int>(PixelFlag::kOutsideMask);
    const int is_solved = flag == static_cast<int>(PixelFlag::kSolved);
    rejected += is_outside ? 0 : lights - lit;
    subset += is_solved & (lit < lights ? 1 : 0);
    solved += is_solved;
    outside += is_outside;
    too_few += flag == static_cast<int>(PixelFlag::kTooFewLights);
    ill += flag == static_cast<int>(PixelFlag::kIllConditioned);
  }
  return {rejected, subset, solved, outside, too_few, ill};
}

// The exact verdict for a pixel whose subset the float kernel could not vouch
// for: G_S summed again in double, its condition number from eigenvalues, and
// if acceptable the solution in double. Rare (few usable lights, or a near
// coplanar subset), so plain scalar code.
struct ExactSubset {
  bool conditioned = false;
  Eigen::Vector3d x = Eigen::Vector3d::Zero();
  float confidence = 0.0f;
};

ExactSubset SolveSubsetExactly(const PhotometricStack& stack, const TileConstants& c, int pixel, float dark,
                               double max_condition2) {
  Eigen::Matrix3d g = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  double b2 = 0.0, sum_u = 0.0, sum_signal = 0.0;
  int usable = 0;
  for (int l = 0; l < c.lights; ++l) {
    const float v = c.planes[l][pixel];
    if (!(v > dark + c.shadow) || !(v < c.saturation)) continue;
    const double u = 1.0 / (stack.light_scales[l] * stack.light_scales[l]);
    const double signal = double(v) - dark, b = signal / stack.light_scales[l];
    const Eigen::Vector3d& w = stack.light_directions[l];
    g += w * w.transpose();
    rhs += b * w;
    b2 += b * b;
    sum_u += u;
    sum_signal += signal * u;
    ++usable;
  }
  ExactSubset result;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen;
  eigen.computeDirect(g, Eigen::EigenvaluesOnly);
  const Eigen::Vector3d lambda = eigen.eigenvalues();  // ascending
  // cond(A_S) = sqrt(cond(G_S)), G_S = A_S^T A_S.
  if (!(lambda(0) > 0.0) || !(lambda(2) <= max_condition2 * lambda(0))) return result;
  result.conditioned = true;
  result.x = g.ldlt().solve(rhs);
  const double rss = std::max(0.0, b2 - result.x.dot(rhs));
  const double expected = (c.read_variance * sum_u + c.shot_gain * sum_signal) * (usable - 3.0) / usable;
  result.confidence = Confidence(rss, expected, b2, usable);
  return result;
}

// The kernels' constants and the arrays they point into, for one stack.
class TileSetup {
 public:
  TileSetup(const LambertianOptions& options, const PhotometricStack& stack, const GlobalSolver& global);
  TileSetup(const TileSetup&) = delete;
  TileSetup& operator=(const TileSetup&) = delete;
  const TileConstants& constants() const { return constants_; }

 private:
  std::vector<const float*> planes_;
  std::vector<float> weights_, inverse_scale2_, inverse_scale_, direction_;
  std::vector<float> group_terms_;  // for the active subset kernel's group size
  std::vector<float> light_lanes_;  // TileConstants::light_lanes_avx2, for the AVX2 kernel only
  TileConstants constants_;
};

// TileConstants::group_terms for groups of `group_size` lights.
std::vector<float> GroupTerms(const PhotometricStack& stack, int group_size) {
  const int k = stack.light_count(), groups = (k + group_size - 1) / group_size, patterns = 1 << group_size;
  std::vector<float> terms(static_cast<std::size_t>(groups) * kGroupQuantities * patterns, 0.0f);
  for (int g = 0; g < groups; ++g) {
    for (int pattern = 0; pattern < patterns; ++pattern) {
      std::array<double, kGroupQuantities> sum{};
      for (int j = 0; j < group_size && group_size * g + j < k; ++j) {
        if (!(pattern & (1 << j))) continue;
        const int light = group_size * g + j;
        const Eigen::Vector3d& w = stack.light_directions[light];
        const std::array<double, kGroupQuantities> term = {
            w.x() * w.x(), w.y() * w.y(), w.z() * w.z(), w.x() * w.y(), w.x() * w.z(), w.y() * w.z(), 1.0,
            1.0 / (stack.light_scales[light] * stack.light_scales[light])};
        for (int q = 0; q < kGroupQuantities; ++q) sum[q] += term[q];
      }
      for (int q = 0; q < kGroupQuantities; ++q)
        terms[(static_cast<std::size_t>(g) * kGroupQuantities + q) * patterns + pattern] = static_cast<float>(sum[q]);
    }
  }
  return terms;
}

TileSetup::TileSetup(const LambertianOptions& options, const PhotometricStack& stack, const GlobalSolver& global) {
  const int k = stack.light_count();
  planes_.resize(k);
  for (int i = 0; i < k; ++i) planes_[i] = stack.images[i].ptr<float>();
  // For the L2 residual without a second pass:
  //   RSS = sum_k b_k^2 - x^T G x,  G = A^T A,  b_k = (I_k - D) / s_k,
  // and sum_k b_k^2 = sum I^2/s^2 - 2 D sum I/s^2 + D^2 sum 1/s^2.
  weights_.resize(3 * static_cast<std::size_t>(k));
  inverse_scale2_.resize(k);
  inverse_scale_.resize(k);
  direction_.resize(3 * static_cast<std::size_t>(k));
  Eigen::Matrix3d gram = Eigen::Matrix3d::Zero();
  TileConstants& c = constants_;
  for (int i = 0; i < k; ++i) {
    const Eigen::Vector3d& w = stack.light_directions[i];
    for (int axis = 0; axis < 3; ++axis) {
      weights_[axis * k + i] = global.weights(axis, i);
      c.dark_weight[axis] += global.weights(axis, i);  // dark subtraction folded into one term
      direction_[axis * k + i] = static_cast<float>(w(axis));
    }
    inverse_scale2_[i] = static_cast<float>(1.0 / (stack.light_scales[i] * stack.light_scales[i]));
    inverse_scale_[i] = static_cast<float>(1.0 / stack.light_scales[i]);
    c.sum_inverse_scale2 += inverse_scale2_[i];
    gram += w * w.transpose();
  }
  // Only the table the solve's kernel reads.
  const SubsetKernel kernel = ActiveSubsetKernel();
  if (kernel == SubsetKernel::kAvx512) group_terms_ = GroupTerms(stack, kSubsetGroup);
  if (kernel == SubsetKernel::kAvx2) group_terms_ = GroupTerms(stack, kSubsetGroupAvx2);
  c.group_terms = kernel == SubsetKernel::kAvx512 ? group_terms_.data() : nullptr;
  c.group_terms_avx2 = kernel == SubsetKernel::kAvx2 ? group_terms_.data() : nullptr;
  if (kernel == SubsetKernel::kAvx2) {
    constexpr int kLanes = 8;
    light_lanes_.resize(static_cast<std::size_t>(k) * 4 * kLanes);
    for (int i = 0; i < k; ++i)
      for (int q = 0; q < 4; ++q)
        std::fill_n(light_lanes_.begin() + (static_cast<std::ptrdiff_t>(i) * 4 + q) * kLanes, kLanes,
                    q < 3 ? static_cast<float>(stack.light_directions[i](q)) : inverse_scale_[i]);
  }
  c.light_lanes_avx2 = kernel == SubsetKernel::kAvx2 ? light_lanes_.data() : nullptr;
  c.planes = planes_.data();
  c.lights = k;
  c.weights = weights_.data();
  c.inverse_scale2 = inverse_scale2_.data();
  c.inverse_scale = inverse_scale_.data();
  for (int axis = 0; axis < 3; ++axis) c.direction[axis] = direction_.data() + axis * k;
  c.gram = {gram(0, 0), gram(1, 1), gram(2, 2), gram(0, 1), gram(0, 2), gram(1, 2)};
  c.read_variance = stack.noise.read_sigma * stack.noise.read_sigma;
  c.shot_gain = stack.noise.shot_gain;
  c.shadow = static_cast<float>(options.shadow_threshold);
  c.saturation = std::isfinite(options.saturation_level) ? static_cast<float>(options.saturation_level)
                                                         : std::numeric_limits<float>::infinity();
  // cond(A_S)^2 = cond(G_S) <= |G_S|_F |G_S^-1|_F: squared once more for the
  // kernel's squared norms, with 1 % room for float rounding on the safe side.
  const double max_condition2 = options.max_condition_number * options.max_condition_number;
  c.max_frobenius_condition2 = static_cast<float>(0.99 * max_condition2 * max_condition2);
}

// Fails, ending *summary, where the options or the stack cannot be solved.
bool CheckInputs(const LambertianOptions& options, const PhotometricStack& stack, SolverSummary* summary) {
  if (solvers::core::EndIfInvalid(options, summary)) return false;
  if (std::string why; !stack.IsValid(&why)) {
    summary->End(Termination::kInvalidInput, "invalid stack: " + why);
    return false;
  }
  const int k = stack.light_count();
  if (k < 3) {
    summary->End(Termination::kInvalidInput, "photometric stereo needs at least 3 lights, got " + std::to_string(k));
    return false;
  }
  if (k > kMaxLights) {
    summary->End(Termination::kInvalidInput, "at most " + std::to_string(kMaxLights) + " lights are supported, got " +
                                                 std::to_string(k));
    return false;
  }
  return true;
}

// Every output map at the stack's size; the tile pass writes each pixel
// once, so none is filled beforehand.
void CreateOutputs(int width, int height, NormalMap* result) {
  result->normals.create(height, width, CV_32FC3);
  result->albedo.create(height, width, CV_32F);
  result->flags.create(height, width, CV_8U);
  result->usable_lights.create(height, width, CV_16U);
  result->model.create(height, width, CV_8U);
  result->confidence.create(height, width, CV_32F);
  result->specular.create(height, width, CV_32FC2);
}

// Solves the tile of n pixels at `begin` into scratch->solution with the
// kernels, its dark levels into scratch->sums.dark. `expect_lit`: whether the
// thread's previous tile was fully lit; returns that for this tile.
bool SolveTileKernels(const LambertianOptions& options, const TileConstants& constants, const float* dark,
                      const std::uint8_t* mask, int begin, int n, bool expect_lit, TileScratch* scratch) {
  TileSums* const sums = &scratch->sums;
  TileSolution* const solution = &scratch->solution;
  SubsetBlock* const block = &scratch->block;
  const int k = constants.lights;
  if (dark)
    std::copy_n(dark + begin, n, sums->dark);
  else
    std::fill_n(sums->dark, n, 0.0f);
  // Every sample is read exactly once from memory. A tile of fully lit
  // pixels costs least with the pseudo-inverse pass; where pixels have
  // shadowed or clipped samples, the subset kernel reads the tile itself.
  // Which one a tile starts with is a guess from the thread's previous
  // tile (neighbouring tiles look alike); a wrong guess of "lit" costs a
  // second look at the affected chunks, from cache.
  // Chunks without a pixel inside the mask are not solved at all: WriteTile
  // marks their pixels outside whatever their (stale) solution says.
  std::array<bool, kTilePixels / kChunkPixels> inside;
  bool any_inside = false;
  for (int chunk = 0; chunk < n; chunk += kChunkPixels) {
    const int chunk_end = std::min(n, chunk + kChunkPixels);
    bool in = mask == nullptr;
    for (int i = chunk; !in && i < chunk_end; ++i) in = mask[begin + i] != 0;
    inside[chunk / kChunkPixels] = in;
    any_inside |= in;
  }
  auto inside_chunk = [&inside](int chunk, int) { return inside[chunk / kChunkPixels]; };
  auto all_lit = [&](int chunk, int chunk_end) {
    return CountPartlyUsable(solution->usable + chunk, chunk_end - chunk, static_cast<float>(k)) == 0;
  };
  auto solve_subsets = [&](int first, int end) {
    SolveSubsetTile(constants, begin, first, end, sums->dark, block, solution);
  };
  if (!any_inside) {
    // Nothing to solve; the guess for the next tile stands.
  } else if (options.exclude_unusable_samples && !expect_lit) {
    ForEachRunOfChunks(n, inside_chunk, solve_subsets);
    std::array<bool, kTilePixels / kChunkPixels> lit;
    expect_lit = true;
    for (int chunk = 0; chunk < n; chunk += kChunkPixels) {
      lit[chunk / kChunkPixels] = inside[chunk / kChunkPixels] && all_lit(chunk, std::min(n, chunk + kChunkPixels));
      expect_lit &= !inside[chunk / kChunkPixels] || lit[chunk / kChunkPixels];
    }
    // A fully lit chunk takes the pseudo-inverse's answer whichever pass came
    // first, as it does when the guess was "lit": the two round differently,
    // and a pixel's result must not depend on which tile its thread solved
    // before (thread scheduling). The second pass reads the chunk from cache.
    ForEachRunOfChunks(
        n, [&lit](int chunk, int) { return lit[chunk / kChunkPixels]; },
        [&](int first, int end) {
          AccumulateTile(constants, begin, first, end, sums);
          SolveLitTile(constants, first, end, *sums, solution);
        });
  } else {
    ForEachRunOfChunks(n, inside_chunk, [&](int first, int end) {
      AccumulateTile(constants, begin, first, end, sums);
      SolveLitTile(constants, first, end, *sums, solution);
    });
    expect_lit = true;
    if (options.exclude_unusable_samples) {
      // The chunks with shadowed or clipped samples get their own subsets.
      ForEachRunOfChunks(
          n,
          [&](int chunk, int chunk_end) {
            const bool needed = inside[chunk / kChunkPixels] && !all_lit(chunk, chunk_end);
            expect_lit &= !needed;
            return needed;
          },
          solve_subsets);
    }
  }
  return expect_lit;
}

// Subsets the float kernel could not vouch for get the exact verdict; most
// tiles have none, which one vector pass finds out.
void ResolveUnverified(const LambertianOptions& options, const PhotometricStack& stack, const TileConstants& constants,
                       double max_condition2, int begin, int n, const TileScratch& scratch, NormalMap* result) {
  const std::uint16_t* usable = result->usable_lights.ptr<std::uint16_t>() + begin;
  const int unverified = CountUnverified(scratch.solution.certainly_conditioned, usable, n);
  for (int i = 0; options.exclude_unusable_samples && unverified > 0 && i < n; ++i) {
    const int p = begin + i;
    if (scratch.solution.certainly_conditioned[i] != 0.0f || usable[i] < 3) continue;
    const ExactSubset exact = SolveSubsetExactly(stack, constants, p, scratch.sums.dark[i], max_condition2);
    if (!exact.conditioned) {
      WriteUnsolved(p, PixelFlag::kIllConditioned, result);
    } else if (!WriteSolution(p, float(exact.x(0)), float(exact.x(1)), float(exact.x(2)), exact.confidence,
                              result)) {
      WriteUnsolved(p, PixelFlag::kTooFewLights, result);
    }
  }
}

}  // namespace

bool LambertianOptions::IsValid(std::string* why) const {
  if (!(shadow_threshold >= 0.0) || !std::isfinite(shadow_threshold))
    return core::Refuse(why, "shadow_threshold must be finite and >= 0");
  if (!(saturation_level > shadow_threshold)) return core::Refuse(why, "saturation_level must exceed shadow_threshold");
  if (!(max_condition_number > 1.0)) return core::Refuse(why, "max_condition_number must be > 1");
  if (num_threads < 0) return core::Refuse(why, "num_threads must be >= 0 (0 = all)");
  return true;
}

namespace internal {

struct PixelResiduals::Impl {
  GlobalSolver global;
  std::unique_ptr<TileSetup> setup;
  const float* dark = nullptr;
};

PixelResiduals::PixelResiduals(const LambertianOptions& options, const PhotometricStack& stack) {
  if (!options.IsValid(nullptr) || !stack.IsValid(nullptr)) return;
  if (stack.light_count() < 3 || stack.light_count() > kMaxLights) return;
  auto impl = std::make_unique<Impl>();
  impl->global = BuildGlobalSolver(stack);
  if (!(impl->global.condition_number <= options.max_condition_number)) return;
  impl->setup = std::make_unique<TileSetup>(options, stack, impl->global);
  impl->dark = stack.dark.empty() ? nullptr : stack.dark.ptr<float>();
  impl_ = std::move(impl);
}

PixelResiduals::~PixelResiduals() = default;

void PixelResiduals::Fit(std::span<const Run> runs, PixelResidual* out) const {
  static_assert(kMaxRun <= kBlockPixels, "a run is one block of the subset kernel");
  TileScratch& scratch = ThreadTileScratch();
  SubsetBlock* const block = &scratch.block;
  TileSolution* const solution = &scratch.solution;
  alignas(64) float dark[kMaxRun];
  for (const Run& run : runs) {
    for (int i = 0; i < run.count; ++i) dark[i] = impl_->dark ? impl_->dark[run.begin + i] : 0.0f;
    SolveSubsetTile(impl_->setup->constants(), run.begin, 0, run.count, dark, block, solution);
    for (int i = 0; i < run.count; ++i, ++out) {
      out->rss = block->rss[i];
      out->usable = static_cast<int>(block->usable[i]);
      out->sum_inverse_scale2 = block->u[i];
      out->sum_signal_inverse_scale2 = block->signal[i];
      out->conditioned = solution->certainly_conditioned[i] != 0.0f;
    }
  }
}

bool SubsetKernelAvailable(SubsetKernel kernel) { return CpuSupports(kernel); }
void UseSubsetKernel(SubsetKernel kernel) {
  chosen_subset_kernel.store(CpuSupports(kernel) ? static_cast<int>(kernel) : -1, std::memory_order_relaxed);
}
void UseFastestSubsetKernel() { chosen_subset_kernel.store(-1, std::memory_order_relaxed); }

SolverSummary SolveLambertianTiles(const LambertianOptions& options, const PhotometricStack& stack,
                                   NormalMap* result, const TileVisitor& visit, const ThreadDone& done) {
  solvers::core::SolveTimer timer;
  SolverSummary summary;
  summary.method = options.exclude_unusable_samples ? "lambertian" : "lambertian-l2";
  summary.light_count = stack.light_count();
  if (!CheckInputs(options, stack, &summary)) return summary;
  const int k = stack.light_count();

  const GlobalSolver global = BuildGlobalSolver(stack);
  summary.condition_number = global.condition_number;
  if (!(global.condition_number <= options.max_condition_number)) {
    summary.termination = Termination::kFailure;
    summary.message = "light directions are coplanar or nearly so (condition number " +
                      std::to_string(global.condition_number) + " > " +
                      std::to_string(options.max_condition_number) + ")";
    return summary;
  }

  const int width = stack.width(), height = stack.height();
  const int pixels = width * height;
  CreateOutputs(width, height, result);

  const float* dark = stack.dark.empty() ? nullptr : stack.dark.ptr<float>();
  const std::uint8_t* mask = stack.mask.empty() ? nullptr : stack.mask.ptr<std::uint8_t>();
  const TileSetup setup(options, stack, global);
  const TileConstants& constants = setup.constants();
  const double max_condition2 = options.max_condition_number * options.max_condition_number;
  timer.SetupDone(&summary);

  const int tiles = (pixels + kTilePixels - 1) / kTilePixels;
  std::size_t rejected_samples = 0, on_subset = 0;
  std::size_t solved = 0, outside_mask = 0, too_few = 0, ill_conditioned = 0;
  const int threads = options.num_threads > 0 ? options.num_threads : omp_get_max_threads();

#pragma omp parallel num_threads(threads) \
    reduction(+ : rejected_samples, on_subset, solved, outside_mask, too_few, ill_conditioned)
  {
    TileScratch& scratch = ThreadTileScratch();
    bool expect_lit = true;
#pragma omp for schedule(dynamic, 4) nowait
    for (int tile = 0; tile < tiles; ++tile) {
      const int begin = tile * kTilePixels;
      const int n = std::min(kTilePixels, pixels - begin);
      expect_lit = SolveTileKernels(options, constants, dark, mask, begin, n, expect_lit, &scratch);
      WriteTile(begin, n, scratch.solution, mask, result);
      ResolveUnverified(options, stack, constants, max_condition2, begin, n, scratch, result);
      const std::uint16_t* usable = result->usable_lights.ptr<std::uint16_t>() + begin;
      const TileCounts counts = CountTile(result->flags.ptr<std::uint8_t>() + begin, usable, n, k);
      rejected_samples += counts.rejected_samples;
      on_subset += options.exclude_unusable_samples ? counts.on_subset : 0;
      solved += counts.solved;
      outside_mask += counts.outside_mask;
      too_few += counts.too_few;
      ill_conditioned += counts.ill_conditioned;
      if (visit) visit(omp_get_thread_num(), begin, n);
    }
    if (done) done(omp_get_thread_num());
  }

  summary.samples_rejected = rejected_samples;
  summary.pixels_on_light_subsets = on_subset;
  summary.pixels_total = static_cast<std::size_t>(pixels);
  summary.pixels_solved = solved;
  summary.pixels_outside_mask = outside_mask;
  summary.pixels_too_few_lights = too_few;
  summary.pixels_ill_conditioned = ill_conditioned;
  timer.Finish(&summary);
  summary.termination = Termination::kSuccess;
  return summary;
}

}  // namespace internal

SolverSummary SolveLambertian(const LambertianOptions& options, const PhotometricStack& stack,
                              NormalMap* result) {
  return internal::SolveLambertianTiles(options, stack, result, {});
}

}  // namespace photorig::solvers::ps
