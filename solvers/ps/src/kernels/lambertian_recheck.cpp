#include "lambertian_recheck.h"
#include "lane_math.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace photorig::solvers::ps::internal {
namespace {

constexpr int kPixels = kFloatLanes;

// The stack's constants and the conditioning limit of the refit.
struct Constants : PlaneConstants {
  Constants(const PlaneSamples& samples, float max_frobenius_condition2)
      : PlaneConstants(samples), max_frobenius_condition2(max_frobenius_condition2) {}
  float max_frobenius_condition2;
};

// One lane per pixel; a lane past the last pixel repeats pixel 0.
struct Lanes {
  alignas(64) int pixel[kPixels];
  alignas(64) float dark[kPixels];
  alignas(64) float x0[kPixels], x1[kPixels], x2[kPixels];  // in: the Lambertian pass's fit
  alignas(64) float chi2[kPixels], used[kPixels], unlit[kPixels];
  alignas(64) float worst_lit[kPixels], worst_unlit[kPixels];  // largest r^2 / var among lit, unlit samples
  alignas(64) float g[6][kPixels], r[3][kPixels];  // normal equations of the lit samples: xx, yy, zz, xy, xz, yz
  alignas(64) float lit0[kPixels], lit1[kPixels], lit2[kPixels], conditioned[kPixels];  // the refit
  alignas(64) float lit_chi2[kPixels], lit_used[kPixels], moved[kPixels];
};

// Residuals are taken in input units, r = (I - D) - s w.x, so that r^2 /
// Var(I - D) needs no division by s.
PHOTORIG_PS_MULTIVERSION
void TestFit(const Constants& c, Lanes* l) {
  for (int i = 0; i < kPixels; ++i) {
    l->chi2[i] = l->used[i] = l->unlit[i] = l->worst_lit[i] = l->worst_unlit[i] = 0.0f;
    for (auto& row : l->g) row[i] = 0.0f;
    for (auto& row : l->r) row[i] = 0.0f;
  }
  for (int k = 0; k < c.lights; ++k) {
    const float* plane = c.planes[k];
    const float wx = c.wx[k], wy = c.wy[k], wz = c.wz[k], scale = c.scale[k], inverse_scale = c.inverse_scale[k];
#pragma omp simd
    for (int i = 0; i < kPixels; ++i) {
      const float value = plane[l->pixel[i]];
      const float signal = value - l->dark[i];
      const bool usable = c.Usable(value, signal);
      const float prediction = wx * l->x0[i] + wy * l->x1[i] + wz * l->x2[i];
      const float residual = signal - scale * prediction;
      const float variance = c.Variance(signal);
      // 0 / 1 factors rather than conditional updates: a masked store
      // followed by the next light's load of the same lanes is not forwarded.
      const float in = usable ? 1.0f : 0.0f, lit = usable & (prediction > 0.0f) ? 1.0f : 0.0f;
      const float u2 = in * (residual * residual / variance);
      l->chi2[i] += u2;
      l->used[i] += in;
      l->unlit[i] += in - lit;
      l->worst_lit[i] = std::max(l->worst_lit[i], lit * u2);
      l->worst_unlit[i] = std::max(l->worst_unlit[i], (in - lit) * u2);
      const float b = lit * signal * inverse_scale;
      l->g[0][i] += lit * wx * wx, l->g[1][i] += lit * wy * wy, l->g[2][i] += lit * wz * wz;
      l->g[3][i] += lit * wx * wy, l->g[4][i] += lit * wx * wz, l->g[5][i] += lit * wy * wz;
      l->r[0][i] += wx * b, l->r[1][i] += wy * b, l->r[2][i] += wz * b;
    }
  }
}

// The refit of every lane from its lit samples' normal equations, by the
// adjugate, with the tile kernel's Frobenius bound on the conditioning.
PHOTORIG_PS_MULTIVERSION
void SolveLit(const Constants& c, Lanes* l) {
#pragma omp simd
  for (int i = 0; i < kPixels; ++i) {
    const float gxx = l->g[0][i], gyy = l->g[1][i], gzz = l->g[2][i], gxy = l->g[3][i], gxz = l->g[4][i],
                gyz = l->g[5][i];
    const float a00 = gyy * gzz - gyz * gyz, a01 = gxz * gyz - gxy * gzz, a02 = gxy * gyz - gxz * gyy;
    const float a11 = gxx * gzz - gxz * gxz, a12 = gxy * gxz - gxx * gyz, a22 = gxx * gyy - gxy * gxy;
    const float det = gxx * a00 + gxy * a01 + gxz * a02;
    const float inverse_det = det > 0.0f ? 1.0f / det : 0.0f;
    const float rx = l->r[0][i], ry = l->r[1][i], rz = l->r[2][i];
    l->lit0[i] = (a00 * rx + a01 * ry + a02 * rz) * inverse_det;
    l->lit1[i] = (a01 * rx + a11 * ry + a12 * rz) * inverse_det;
    l->lit2[i] = (a02 * rx + a12 * ry + a22 * rz) * inverse_det;
    const float g_norm2 = gxx * gxx + gyy * gyy + gzz * gzz + 2.0f * (gxy * gxy + gxz * gxz + gyz * gyz);
    const float adj_norm2 = a00 * a00 + a11 * a11 + a22 * a22 + 2.0f * (a01 * a01 + a02 * a02 + a12 * a12);
    const float bound = g_norm2 * adj_norm2 * inverse_det * inverse_det;
    l->conditioned[i] = (det > 0.0f) & (bound <= c.max_frobenius_condition2) ? 1.0f : 0.0f;
  }
}

// Chi-square of the refit on the samples it lights, and how many usable
// samples it moves across the terminator compared with the first fit.
PHOTORIG_PS_MULTIVERSION
void TestRefit(const Constants& c, Lanes* l) {
  for (int i = 0; i < kPixels; ++i) l->lit_chi2[i] = l->lit_used[i] = l->moved[i] = 0.0f;
  for (int k = 0; k < c.lights; ++k) {
    const float* plane = c.planes[k];
    const float wx = c.wx[k], wy = c.wy[k], wz = c.wz[k], scale = c.scale[k];
#pragma omp simd
    for (int i = 0; i < kPixels; ++i) {
      const float value = plane[l->pixel[i]];
      const float signal = value - l->dark[i];
      const bool usable = c.Usable(value, signal);
      const bool was_lit = wx * l->x0[i] + wy * l->x1[i] + wz * l->x2[i] > 0.0f;
      const float prediction = wx * l->lit0[i] + wy * l->lit1[i] + wz * l->lit2[i];
      const bool lit = prediction > 0.0f;
      const float residual = signal - scale * prediction;
      const float variance = c.Variance(signal);
      const float counted = usable & lit ? 1.0f : 0.0f;  // as in TestFit, no conditional updates
      l->lit_chi2[i] += counted * (residual * residual / variance);
      l->lit_used[i] += counted;
      l->moved[i] += usable & (lit != was_lit) ? 1.0f : 0.0f;
    }
  }
}

}  // namespace

RecheckLanes::RecheckLanes(const PhotometricStack& stack, const LambertianOptions& options)
    : samples_(stack, options) {
  // As the tile kernel: cond(A)^2 = cond(G) <= |G|_F |G^-1|_F, squared once
  // more for squared norms, with 1 % room for float rounding on the safe side.
  const double max_condition2 = options.max_condition_number * options.max_condition_number;
  max_frobenius_condition2_ = static_cast<float>(0.99 * max_condition2 * max_condition2);
}

void RecheckLanes::CopySamples(std::span<const int> pixels, float* out) const {
  const int lights = samples_.lights();
  // Sixteen pixels at a time, plane by plane. Planes allocated apart start
  // at the same offset within a 4 KB page, so all of a pixel's samples fall
  // in one L1 set (12 ways): copied pixel by pixel, nearly every sample
  // missed L1 (the trimming's copy was 6 % of shiny `auto`). Plane by
  // plane, a block's line of each plane is loaded once for its sixteen
  // pixels, and the block's rows (3 KB at 48 lights) stay in L1 as they fill.
  constexpr std::size_t kBlock = 16;
  for (std::size_t first = 0; first < pixels.size(); first += kBlock) {
    const std::size_t count = std::min(kBlock, pixels.size() - first);
    const int* block = pixels.data() + first;
    float* rows = out + first * lights;
    for (int k = 0; k < lights; ++k) {
      const float* plane = samples_.planes[k];
      for (std::size_t j = 0; j < count; ++j) rows[j * lights + k] = plane[block[j]];
    }
  }
}

void RecheckLanes::Check(std::span<const int> pixels, std::span<const Eigen::Vector3d> x, std::span<Recheck> out,
                         const float* copies) const {
  Constants c(samples_, max_frobenius_condition2_);
  // The copies as planes: light k's "plane" starts at copies + k, and pixel
  // j's sample lies j * lights further on.
  std::vector<const float*> copied_planes;
  if (copies) {
    for (int k = 0; k < c.lights; ++k) copied_planes.push_back(copies + k);
    c.planes = copied_planes.data();
  }
  Lanes lanes;
  for (std::size_t first = 0; first < pixels.size(); first += kPixels) {
    const int count = static_cast<int>(std::min<std::size_t>(kPixels, pixels.size() - first));
    for (int i = 0; i < kPixels; ++i) {
      const std::size_t j = first + (i < count ? i : 0);
      lanes.pixel[i] = copies ? static_cast<int>(j) * c.lights : pixels[j];
      lanes.dark[i] = samples_.dark ? samples_.dark[pixels[j]] : 0.0f;
      lanes.x0[i] = static_cast<float>(x[j].x());
      lanes.x1[i] = static_cast<float>(x[j].y());
      lanes.x2[i] = static_cast<float>(x[j].z());
    }
    TestFit(c, &lanes);
    // As FitLit: the refit only where a sample in attached shadow is the worst misfit.
    bool refit[kPixels] = {};
    bool any_refit = false;
    for (int i = 0; i < count; ++i) {
      refit[i] = lanes.unlit[i] > 0.0f && lanes.worst_unlit[i] >= lanes.worst_lit[i] &&
                 lanes.used[i] - lanes.unlit[i] >= 4.0f;
      any_refit |= refit[i];
    }
    if (any_refit) {
      SolveLit(c, &lanes);
      TestRefit(c, &lanes);
    }
    for (int i = 0; i < count; ++i) {
      Recheck& result = out[first + i];
      result = Recheck{};
      result.chi2 = lanes.chi2[i];
      result.used = static_cast<int>(lanes.used[i]);
      result.unlit = static_cast<int>(lanes.unlit[i]);
      if (!refit[i] || lanes.conditioned[i] == 0.0f || lanes.moved[i] != 0.0f) continue;
      result.refitted = true;
      result.lit_x = Eigen::Vector3d(lanes.lit0[i], lanes.lit1[i], lanes.lit2[i]);
      result.lit_chi2 = lanes.lit_chi2[i];
      result.lit_used = static_cast<int>(lanes.lit_used[i]);
    }
  }
}

}  // namespace photorig::solvers::ps::internal
