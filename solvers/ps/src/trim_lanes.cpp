#include "trim_lanes.h"

#include "lane_least_squares.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace photorig::ps::internal {
namespace {

struct alignas(64) LaneRound {
  double x[3][kLanes];
  double chi2[kLanes];
  double worst_u2[kLanes];
};

// One round for all lanes: x from the normal equations (by the adjugate; a
// singular system gives non-finite x), then every sample's squared
// standardised residual u2 (0 once trimmed), chi-square and the largest u2.
PHOTORIG_PS_MULTIVERSION
void TrimRound(const LaneNormalEquations& eq, int lights, const double* directions, const double* observed,
               const double* weight, LaneRound* out, double* u2_out) {
  alignas(64) double x0[kLanes], x1[kLanes], x2[kLanes], chi2[kLanes], worst[kLanes];
#pragma omp simd
  for (int j = 0; j < kLanes; ++j) {
    const double xx = eq.matrix[0][j], xy = eq.matrix[1][j], xz = eq.matrix[2][j];
    const double yy = eq.matrix[3][j], yz = eq.matrix[4][j], zz = eq.matrix[5][j];
    const double c00 = yy * zz - yz * yz, c01 = xz * yz - xy * zz, c02 = xy * yz - xz * yy;
    const double c11 = xx * zz - xz * xz, c12 = xy * xz - xx * yz, c22 = xx * yy - xy * xy;
    const double inverse_det = 1.0 / (xx * c00 + xy * c01 + xz * c02);
    const double b0 = eq.rhs[0][j], b1 = eq.rhs[1][j], b2 = eq.rhs[2][j];
    x0[j] = (c00 * b0 + c01 * b1 + c02 * b2) * inverse_det;
    x1[j] = (c01 * b0 + c11 * b1 + c12 * b2) * inverse_det;
    x2[j] = (c02 * b0 + c12 * b1 + c22 * b2) * inverse_det;
    chi2[j] = 0.0, worst[j] = 0.0;
  }
  for (int k = 0; k < lights; ++k) {
    const double wx = directions[3 * k], wy = directions[3 * k + 1], wz = directions[3 * k + 2];
    const double* b = observed + k * kLanes;
    const double* v = weight + k * kLanes;
    double* u2 = u2_out + k * kLanes;
#pragma omp simd
    for (int j = 0; j < kLanes; ++j) {
      const double r = b[j] - wx * x0[j] - wy * x1[j] - wz * x2[j];
      u2[j] = r * r * v[j];
      chi2[j] += u2[j];
      worst[j] = std::max(worst[j], u2[j]);
    }
  }
  for (int j = 0; j < kLanes; ++j) {
    out->x[0][j] = x0[j], out->x[1][j] = x1[j], out->x[2][j] = x2[j];
    out->chi2[j] = chi2[j], out->worst_u2[j] = worst[j];
  }
}

// How many samples of each lane have u2 >= threshold[lane].
PHOTORIG_PS_MULTIVERSION
void CountAtLeast(int lights, const double* u2, const double* threshold, double* count) {
  alignas(64) double sum[kLanes] = {};
  for (int k = 0; k < lights; ++k) {
    const double* row = u2 + k * kLanes;
#pragma omp simd
    for (int j = 0; j < kLanes; ++j) sum[j] += row[j] >= threshold[j] ? 1.0 : 0.0;
  }
  for (int j = 0; j < kLanes; ++j) count[j] = sum[j];
}

// Drops every sample with u2 >= threshold[lane] (infinity: none) from its
// lane's normal equations, a rank-one downdate each, and marks it trimmed.
PHOTORIG_PS_MULTIVERSION
void DropSamples(int lights, const double* directions, const double* observed, const double* u2,
                 const double* threshold, double* weight, LaneNormalEquations* eq) {
  LaneNormalEquations dropped = {};  // in registers; subtracted once at the end
  for (int k = 0; k < lights; ++k) {
    const double wx = directions[3 * k], wy = directions[3 * k + 1], wz = directions[3 * k + 2];
    const double* b = observed + k * kLanes;
    const double* row = u2 + k * kLanes;
    double* v = weight + k * kLanes;
#pragma omp simd
    for (int j = 0; j < kLanes; ++j) {
      const double c = row[j] >= threshold[j] ? v[j] : 0.0;
      AddSample(dropped, j, c, b[j], wx, wy, wz);
      v[j] -= c;
    }
  }
  for (int i = 0; i < 6; ++i)
#pragma omp simd
    for (int j = 0; j < kLanes; ++j) eq->matrix[i][j] -= dropped.matrix[i][j];
  for (int i = 0; i < 3; ++i)
#pragma omp simd
    for (int j = 0; j < kLanes; ++j) eq->rhs[i][j] -= dropped.rhs[i][j];
}

// The weighted normal equations of one pixel's samples (v = 1 / sigma^2):
// sums = {xx, xy, xz, yy, yz, zz, bx, by, bz, usable count}.
PHOTORIG_PS_MULTIVERSION
void NormalEquationsOfRow(int lights, const double* directions, const double* observed, const double* inverse_sigma,
                          double* sums) {
  double xx = 0, xy = 0, xz = 0, yy = 0, yz = 0, zz = 0, bx = 0, by = 0, bz = 0, usable = 0;
#pragma omp simd reduction(+ : xx, xy, xz, yy, yz, zz, bx, by, bz, usable)
  for (int k = 0; k < lights; ++k) {
    const double v = inverse_sigma[k] * inverse_sigma[k], b = observed[k];
    const double wx = directions[3 * k], wy = directions[3 * k + 1], wz = directions[3 * k + 2];
    xx += v * wx * wx, xy += v * wx * wy, xz += v * wx * wz, yy += v * wy * wy, yz += v * wy * wz, zz += v * wz * wz;
    bx += v * b * wx, by += v * b * wy, bz += v * b * wz;
    usable += v > 0.0 ? 1.0 : 0.0;
  }
  const double values[10] = {xx, xy, xz, yy, yz, zz, bx, by, bz, usable};
  for (int i = 0; i < 10; ++i) sums[i] = values[i];
}

}  // namespace

struct TrimmedLambertianLanes::State {
  LaneNormalEquations equations;
  LaneRound round;
  int problem[kLanes];  // -1: idle
  int usable[kLanes], removed[kLanes], max_rejected[kLanes];
};

TrimmedLambertianLanes::TrimmedLambertianLanes(const std::vector<Eigen::Vector3d>& light_directions,
                                               double gross_u2)
    : lights_(static_cast<int>(light_directions.size())),
      gross_u2_(gross_u2),
      directions_(DirectionArray(light_directions)),
      observed_(light_directions.size() * kLanes),
      weight_(light_directions.size() * kLanes),
      u2_(light_directions.size() * kLanes),
      state_(std::make_unique<State>()) {}

TrimmedLambertianLanes::~TrimmedLambertianLanes() = default;
TrimmedLambertianLanes::TrimmedLambertianLanes(TrimmedLambertianLanes&&) noexcept = default;

void TrimmedLambertianLanes::Load(int lane, const TrimProblem& problem) {
  State& s = *state_;
  double sums[10];  // the normal equations (6), their right-hand side (3), the usable count
  NormalEquationsOfRow(lights_, directions_.data(), problem.observed, problem.inverse_sigma, sums);
  for (int k = 0; k < lights_; ++k) {
    observed_[k * kLanes + lane] = problem.observed[k];
    weight_[k * kLanes + lane] = problem.inverse_sigma[k] * problem.inverse_sigma[k];
  }
  for (int i = 0; i < 6; ++i) s.equations.matrix[i][lane] = sums[i];
  for (int i = 0; i < 3; ++i) s.equations.rhs[i][lane] = sums[6 + i];
  s.usable[lane] = static_cast<int>(sums[9]);
  s.removed[lane] = 0;
  s.max_rejected[lane] = problem.max_rejected;
}

void TrimmedLambertianLanes::Fit(std::span<const TrimProblem> problems, std::span<const double> chi2_quantile,
                                 std::span<TrimSolution> solutions) {
  State& s = *state_;
  const int count = static_cast<int>(problems.size());
  // An idle lane solves the identity system on no samples: finite, ignored.
  auto idle = [&](int lane) {
    for (int k = 0; k < lights_; ++k) observed_[k * kLanes + lane] = weight_[k * kLanes + lane] = 0.0;
    for (int i = 0; i < 6; ++i) s.equations.matrix[i][lane] = (i == 0 || i == 3 || i == 5) ? 1.0 : 0.0;
    for (int i = 0; i < 3; ++i) s.equations.rhs[i][lane] = 0.0;
  };
  LaneQueue queue(count);
  auto load = [&](int lane, int index) { Load(lane, problems[index]); };
  auto refill = [&](int lane) { queue.Refill(lane, s.problem, load, idle); };
  for (int lane = 0; lane < kLanes; ++lane) refill(lane);
  while (queue.busy() > 0) {
    TrimRound(s.equations, lights_, directions_.data(), observed_.data(), weight_.data(), &s.round, u2_.data());
    // Which samples each lane would drop (infinity: it is done) ...
    alignas(64) double threshold[kLanes], drop[kLanes];
    bool ok[kLanes];
    for (int lane = 0; lane < kLanes; ++lane) {
      threshold[lane] = std::numeric_limits<double>::infinity();
      if (s.problem[lane] < 0) continue;
      const int used = s.usable[lane] - s.removed[lane];
      ok[lane] = Eigen::Vector3d(s.round.x[0][lane], s.round.x[1][lane], s.round.x[2][lane]).norm() > 0.0 &&
                 used >= 3;  // false for a non-finite x too
      const bool adequate = ok[lane] && used > 3 && s.round.chi2[lane] <= chi2_quantile[used - 3];
      const double t = TrimThreshold(s.round.worst_u2[lane], gross_u2_);
      if (ok[lane] && !adequate && t > 0.0) threshold[lane] = t;
    }
    CountAtLeast(lights_, u2_.data(), threshold, drop);
    // ... and whether it may: a lane that is done, or would exceed its
    // allowance, hands over its fit and takes the next pixel.
    for (int lane = 0; lane < kLanes; ++lane) {
      if (s.problem[lane] < 0) continue;
      const int used = s.usable[lane] - s.removed[lane];
      const int dropped = static_cast<int>(drop[lane]);
      if (std::isfinite(threshold[lane]) && s.removed[lane] + dropped <= s.max_rejected[lane] && used - dropped >= 3) {
        s.removed[lane] += dropped;
        continue;
      }
      threshold[lane] = std::numeric_limits<double>::infinity();
      TrimSolution& out = solutions[s.problem[lane]];
      out.x = Eigen::Vector3d(s.round.x[0][lane], s.round.x[1][lane], s.round.x[2][lane]);
      out.ok = ok[lane];
      out.chi2 = s.round.chi2[lane];
      out.used = used;
      out.rejected = s.removed[lane];
      refill(lane);
    }
    DropSamples(lights_, directions_.data(), observed_.data(), u2_.data(), threshold, weight_.data(), &s.equations);
  }
}

}  // namespace photorig::ps::internal
