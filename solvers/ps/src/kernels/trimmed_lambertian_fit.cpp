#include "trimmed_lambertian_fit.h"

#include <cmath>
#include <limits>

namespace photorig::solvers::ps::internal {
namespace {

constexpr int kPixels = kFloatLanes;

// Weighted normal equations of each lane: sum c w w^T (xx, xy, xz, yy, yz,
// zz) and sum c b w.
struct alignas(64) LaneSums {
  float matrix[6][kPixels];
  float rhs[3][kPixels];
};

struct alignas(64) Lanes {
  LaneSums equations;
  float x[3][kPixels], chi2[kPixels], worst_u2[kPixels];  // the last round's
  float threshold[kPixels], dropped[kPixels];
  LaneSums kept;  // the normal equations without the samples over threshold
};

// Where CopySamples puts what in a pixel's row of length() floats.
struct RowLayout {
  explicit RowLayout(int lights) : lights(lights) {}
  int dark() const { return lights; }
  int observed() const { return lights + 1; }  // b = (I - D) / s per light
  int weight() const { return 2 * lights + 1; }  // its weight, 0 where unusable
  int sums() const { return 3 * lights + 1; }  // normal equations (9), usable count
  int length() const { return 3 * lights + 11; }
  int lights;
};

// A pixel's samples in solver units from its raw values: b and its weight for
// every light, and the normal equations of its usable samples, one pass over
// the lights in vector lanes.
PHOTORIG_PS_MULTIVERSION
void PrepareRow(const PlaneConstants& c, float weight_unit, float* row) {
  const RowLayout layout(c.lights);
  const float dark = row[layout.dark()];
  const float* raw = row;
  float* __restrict observed = row + layout.observed();
  float* __restrict weight = row + layout.weight();
  const float *wx = c.wx, *wy = c.wy, *wz = c.wz, *scale = c.scale, *inverse_scale = c.inverse_scale;
  float xx = 0, xy = 0, xz = 0, yy = 0, yz = 0, zz = 0, bx = 0, by = 0, bz = 0, usable = 0;
#pragma omp simd reduction(+ : xx, xy, xz, yy, yz, zz, bx, by, bz, usable)
  for (int k = 0; k < c.lights; ++k) {
    const float value = raw[k], signal = value - dark;
    const bool ok = c.Usable(value, signal);
    const float v = ok ? scale[k] * scale[k] * weight_unit / c.Variance(signal) : 0.0f;
    const float b = ok ? signal * inverse_scale[k] : 0.0f;
    observed[k] = b, weight[k] = v;
    xx += v * wx[k] * wx[k], xy += v * wx[k] * wy[k], xz += v * wx[k] * wz[k];
    yy += v * wy[k] * wy[k], yz += v * wy[k] * wz[k], zz += v * wz[k] * wz[k];
    bx += v * b * wx[k], by += v * b * wy[k], bz += v * b * wz[k];
    usable += ok ? 1.0f : 0.0f;
  }
  const float sums[10] = {xx, xy, xz, yy, yz, zz, bx, by, bz, usable};
  for (int i = 0; i < 10; ++i) row[layout.sums() + i] = sums[i];
}

// One round for all lanes: x from the normal equations (by the adjugate; a
// singular system gives non-finite x), then every sample's squared
// standardised residual u2 (0 once trimmed), chi-square and the largest u2.
PHOTORIG_PS_MULTIVERSION
void TrimRound(const PlaneConstants& c, float inverse_weight_unit, const float* observed, const float* weight,
               Lanes* l, float* u2_out) {
  alignas(64) float x0[kPixels], x1[kPixels], x2[kPixels], chi2[kPixels], worst[kPixels];
#pragma omp simd
  for (int i = 0; i < kPixels; ++i) {
    const LaneSums& eq = l->equations;
    const float xx = eq.matrix[0][i], xy = eq.matrix[1][i], xz = eq.matrix[2][i];
    const float yy = eq.matrix[3][i], yz = eq.matrix[4][i], zz = eq.matrix[5][i];
    const float c00 = yy * zz - yz * yz, c01 = xz * yz - xy * zz, c02 = xy * yz - xz * yy;
    const float c11 = xx * zz - xz * xz, c12 = xy * xz - xx * yz, c22 = xx * yy - xy * xy;
    const float inverse_det = 1.0f / (xx * c00 + xy * c01 + xz * c02);
    const float b0 = eq.rhs[0][i], b1 = eq.rhs[1][i], b2 = eq.rhs[2][i];
    x0[i] = (c00 * b0 + c01 * b1 + c02 * b2) * inverse_det;
    x1[i] = (c01 * b0 + c11 * b1 + c12 * b2) * inverse_det;
    x2[i] = (c02 * b0 + c12 * b1 + c22 * b2) * inverse_det;
    chi2[i] = 0.0f, worst[i] = 0.0f;
  }
  for (int k = 0; k < c.lights; ++k) {
    const float wx = c.wx[k], wy = c.wy[k], wz = c.wz[k];
    const float* b = observed + k * kPixels;
    const float* v = weight + k * kPixels;
    float* u2 = u2_out + k * kPixels;
#pragma omp simd
    for (int i = 0; i < kPixels; ++i) {
      const float r = b[i] - wx * x0[i] - wy * x1[i] - wz * x2[i];
      u2[i] = r * r * v[i] * inverse_weight_unit;
      chi2[i] += u2[i];
      worst[i] = std::max(worst[i], u2[i]);
    }
  }
  for (int i = 0; i < kPixels; ++i) {
    l->x[0][i] = x0[i], l->x[1][i] = x1[i], l->x[2][i] = x2[i];
    l->chi2[i] = chi2[i], l->worst_u2[i] = worst[i];
  }
}

// Marks every sample with u2 >= threshold[lane] (infinity: none) trimmed,
// counts them, and sums the normal equations of the samples kept (summed
// afresh rather than downdated: no cancellation in float). The caller takes
// them for the lanes that may drop those samples; a lane that may not hands
// over its pixel, and the next one is loaded over its samples.
PHOTORIG_PS_MULTIVERSION
void DropSamples(const PlaneConstants& c, const float* observed, const float* u2, float* weight, Lanes* l) {
  alignas(64) float sums[10][kPixels] = {};
  for (int k = 0; k < c.lights; ++k) {
    const float wx = c.wx[k], wy = c.wy[k], wz = c.wz[k];
    const float* b = observed + k * kPixels;
    const float* row = u2 + k * kPixels;
    float* v = weight + k * kPixels;
#pragma omp simd
    for (int i = 0; i < kPixels; ++i) {
      const bool drop = row[i] >= l->threshold[i];
      const float w = drop ? 0.0f : v[i], bw = w * b[i];
      sums[0][i] += w * wx * wx, sums[1][i] += w * wx * wy, sums[2][i] += w * wx * wz;
      sums[3][i] += w * wy * wy, sums[4][i] += w * wy * wz, sums[5][i] += w * wz * wz;
      sums[6][i] += bw * wx, sums[7][i] += bw * wy, sums[8][i] += bw * wz;
      sums[9][i] += drop ? 1.0f : 0.0f;
      v[i] = w;
    }
  }
  for (int i = 0; i < kPixels; ++i) {
    for (int e = 0; e < 6; ++e) l->kept.matrix[e][i] = sums[e][i];
    for (int e = 0; e < 3; ++e) l->kept.rhs[e][i] = sums[6 + e][i];
    l->dropped[i] = sums[9][i];
  }
}

}  // namespace

struct TrimmedLambertianLanes::State {
  Lanes lanes;
  int problem[kPixels];  // -1: idle
  int usable[kPixels], removed[kPixels], max_rejected[kPixels];
};

TrimmedLambertianLanes::TrimmedLambertianLanes(const PhotometricStack& stack, const LambertianOptions& options,
                                               double gross_u2, double max_rejected_fraction)
    : samples_(stack, options),
      gross_u2_(gross_u2),
      max_rejected_fraction_(max_rejected_fraction),
      observed_(stack.light_count() * kPixels),
      weight_(stack.light_count() * kPixels),
      u2_(stack.light_count() * kPixels),
      state_(std::make_unique<State>()) {
  // A usable sample has I - D > max(shadow threshold, 0), so its variance is
  // at least that of the threshold; its weight s^2 / variance is at most the
  // largest s^2 over that.
  double largest_scale2 = 0.0;
  for (const double s : stack.light_scales) largest_scale2 = std::max(largest_scale2, s * s);
  const double smallest_variance = stack.noise.Variance(std::max(options.shadow_threshold, 0.0));
  const double unit = smallest_variance / largest_scale2;
  if (std::isfinite(unit) && unit > 0.0) weight_unit_ = static_cast<float>(unit);
}

TrimmedLambertianLanes::~TrimmedLambertianLanes() = default;
TrimmedLambertianLanes::TrimmedLambertianLanes(TrimmedLambertianLanes&&) noexcept = default;

int TrimmedLambertianLanes::row_length() const { return RowLayout(samples_.lights()).length(); }

void TrimmedLambertianLanes::CopySamples(int pixel, float* row, const float* values) const {
  const int lights = samples_.lights();
  for (int k = 0; k < lights; ++k) row[k] = values ? values[k] : samples_.planes[k][pixel];
  row[RowLayout(lights).dark()] = samples_.dark ? samples_.dark[pixel] : 0.0f;
  PrepareRow(PlaneConstants(samples_), weight_unit_, row);
}

void TrimmedLambertianLanes::Fit(std::span<const float> rows, std::span<const double> chi2_quantile,
                                 std::span<TrimSolution> solutions) {
  State& s = *state_;
  Lanes& l = s.lanes;
  const PlaneConstants c(samples_);
  const RowLayout layout(c.lights);
  const int count = static_cast<int>(rows.size()) / layout.length();
  const float inverse_weight_unit = 1.0f / weight_unit_;
  auto load = [&](int lane, int index) {
    const float* row = &rows[static_cast<std::size_t>(index) * layout.length()];
    for (int k = 0; k < c.lights; ++k) {
      observed_[k * kPixels + lane] = row[layout.observed() + k];
      weight_[k * kPixels + lane] = row[layout.weight() + k];
    }
    const float* sums = row + layout.sums();
    for (int e = 0; e < 6; ++e) l.equations.matrix[e][lane] = sums[e];
    for (int e = 0; e < 3; ++e) l.equations.rhs[e][lane] = sums[6 + e];
    s.usable[lane] = static_cast<int>(sums[9]);
    s.removed[lane] = 0;
    s.max_rejected[lane] = static_cast<int>(max_rejected_fraction_ * s.usable[lane]);
  };
  // An idle lane solves the identity system on no samples: finite, ignored.
  auto idle = [&](int lane) {
    for (int k = 0; k < c.lights; ++k) observed_[k * kPixels + lane] = weight_[k * kPixels + lane] = 0.0f;
    for (int e = 0; e < 6; ++e) l.equations.matrix[e][lane] = (e == 0 || e == 3 || e == 5) ? 1.0f : 0.0f;
    for (int e = 0; e < 3; ++e) l.equations.rhs[e][lane] = 0.0f;
  };
  LaneQueue queue(count, kPixels);
  auto refill = [&](int lane) { queue.Refill(lane, s.problem, load, idle); };
  for (int lane = 0; lane < kPixels; ++lane) refill(lane);
  while (queue.busy() > 0) {
    TrimRound(c, inverse_weight_unit, observed_.data(), weight_.data(), &l, u2_.data());
    // Which samples each lane would drop (infinity: it is done) ...
    bool ok[kPixels] = {};
    for (int lane = 0; lane < kPixels; ++lane) {
      l.threshold[lane] = std::numeric_limits<float>::infinity();
      if (s.problem[lane] < 0) continue;
      const int used = s.usable[lane] - s.removed[lane];
      const double x_norm2 = double(l.x[0][lane]) * l.x[0][lane] + double(l.x[1][lane]) * l.x[1][lane] +
                             double(l.x[2][lane]) * l.x[2][lane];
      ok[lane] = x_norm2 > 0.0 && used >= 3;  // false for a non-finite x too
      const bool adequate = ok[lane] && used > 3 && l.chi2[lane] <= chi2_quantile[used - 3];
      const double t = TrimThreshold(l.worst_u2[lane], gross_u2_);
      if (ok[lane] && !adequate && t > 0.0) l.threshold[lane] = static_cast<float>(t);
    }
    DropSamples(c, observed_.data(), u2_.data(), weight_.data(), &l);
    // ... and whether it may: a lane that is done, or would exceed its
    // allowance, hands over its fit and takes the next pixel.
    for (int lane = 0; lane < kPixels; ++lane) {
      if (s.problem[lane] < 0) continue;
      const int used = s.usable[lane] - s.removed[lane];
      const int dropped = static_cast<int>(l.dropped[lane]);
      if (std::isfinite(l.threshold[lane]) && s.removed[lane] + dropped <= s.max_rejected[lane] &&
          used - dropped >= 3) {
        s.removed[lane] += dropped;
        for (int e = 0; e < 6; ++e) l.equations.matrix[e][lane] = l.kept.matrix[e][lane];
        for (int e = 0; e < 3; ++e) l.equations.rhs[e][lane] = l.kept.rhs[e][lane];
        continue;
      }
      TrimSolution& out = solutions[s.problem[lane]];
      out.x = Eigen::Vector3d(l.x[0][lane], l.x[1][lane], l.x[2][lane]);
      out.ok = ok[lane];
      out.chi2 = l.chi2[lane];
      out.used = used;
      out.rejected = s.removed[lane];
      refill(lane);
    }
  }
}

}  // namespace photorig::solvers::ps::internal
