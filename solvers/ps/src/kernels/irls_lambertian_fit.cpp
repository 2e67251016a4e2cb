#include "irls_lambertian_fit.h"

#include "normal_equations.h"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace photorig::solvers::ps::internal {
namespace {

// Tuning constants for 95 % efficiency under Gaussian noise.
constexpr double kCauchyScale = 2.385, kHuberScale = 1.345, kTukeyScale = 4.685;

struct alignas(64) LaneVector {
  double v[3][kLanes];
};

// Light k's direction for lane j: one row all lanes share (distant lights),
// or each lane's own (near lights: directions[(3 k + axis) kLanes + j]).
struct LaneDirection {
  double x, y, z;
};
template <bool kPerLane>
PHOTORIG_LANE_INLINE LaneDirection DirectionOf(const double* directions, int k, int j) {
  if constexpr (kPerLane) {
    const double* d = directions + 3 * k * kLanes + j;
    return {d[0], d[kLanes], d[2 * kLanes]};
  } else {
    return {directions[3 * k], directions[3 * k + 1], directions[3 * k + 2]};
  }
}

// Residuals at x, their magnitudes (+infinity for unusable samples, which
// so sort after every usable one), and chi-square and the count of the
// inliers under the current weights (what a lane that has just converged
// reports).
template <bool kPerLane>
PHOTORIG_LANE_INLINE void ResidualsOf(int lights, const double* directions, const double* observed,
                                      const double* inverse_variance, const double* weight, double inlier_weight,
                                      const LaneVector& x, double* residual, double* magnitude, double* chi2_out,
                                      double* used_out) {
  alignas(64) double chi2[kLanes] = {}, used[kLanes] = {};
  for (int k = 0; k < lights; ++k) {
    const double* b = observed + k * kLanes;
    const double* v = inverse_variance + k * kLanes;
    const double* c = weight + k * kLanes;
    double* r = residual + k * kLanes;
    double* m = magnitude + k * kLanes;
#pragma omp simd
    for (int j = 0; j < kLanes; ++j) {
      const LaneDirection w = DirectionOf<kPerLane>(directions, k, j);
      r[j] = b[j] - w.x * x.v[0][j] - w.y * x.v[1][j] - w.z * x.v[2][j];
      m[j] = v[j] > 0.0 ? std::abs(r[j]) : std::numeric_limits<double>::infinity();
      const double inlier = (v[j] > 0.0) & (c[j] >= inlier_weight) ? 1.0 : 0.0;
      chi2[j] += inlier * v[j] * r[j] * r[j];
      used[j] += inlier;
    }
  }
  for (int j = 0; j < kLanes; ++j) chi2_out[j] = chi2[j], used_out[j] = used[j];
}

PHOTORIG_PS_MULTIVERSION
void Residuals(bool per_lane, int lights, const double* directions, const double* observed,
               const double* inverse_variance, const double* weight, double inlier_weight, const LaneVector& x,
               double* residual, double* magnitude, double* chi2_out, double* used_out) {
  if (per_lane)
    ResidualsOf<true>(lights, directions, observed, inverse_variance, weight, inlier_weight, x, residual, magnitude,
                      chi2_out, used_out);
  else
    ResidualsOf<false>(lights, directions, observed, inverse_variance, weight, inlier_weight, x, residual, magnitude,
                       chi2_out, used_out);
}

// The weights of the loss each lane is in (one of the three selectors is 1,
// the others 0: formulas without branches, so the loop vectorises), and the
// weighted normal equations.
template <bool kPerLane>
PHOTORIG_LANE_INLINE void WeightsAndNormalEquationsOf(int lights, const double* directions, const double* observed,
                                                      const double* inverse_variance, const double* inverse_sigma,
                                                      const double* residual, const double* inverse_spread,
                                                      const double* cauchy, const double* huber, const double* tukey,
                                                      double* weight, LaneNormalEquations* eq) {
  LaneNormalEquations sums = {};  // in registers; stored once at the end
  for (int k = 0; k < lights; ++k) {
    const double* b = observed + k * kLanes;
    const double* v = inverse_variance + k * kLanes;
    const double* r = residual + k * kLanes;
    double* weight_k = weight + k * kLanes;
#pragma omp simd
    for (int j = 0; j < kLanes; ++j) {
      // u^2 = r^2 / max(sigma, spread)^2, by products: 1 / max(a, b) = min(1 / a, 1 / b).
      const double scale = std::min(inverse_sigma[k * kLanes + j], inverse_spread[j]);
      const double u2 = r[j] * r[j] * scale * scale;
      const double biweight = 1.0 - std::min(u2 * (1.0 / (kTukeyScale * kTukeyScale)), 1.0);  // 0 beyond the cut-off
      // The two divisions in float: a weight needs no more than its 7 digits.
      const float u2f = static_cast<float>(u2);
      const double cauchy_weight = 1.0f / (1.0f + u2f * static_cast<float>(1.0 / (kCauchyScale * kCauchyScale)));
      const double huber_weight = std::min(1.0f, static_cast<float>(kHuberScale) / std::sqrt(u2f));
      const double w = cauchy[j] * cauchy_weight + huber[j] * huber_weight + tukey[j] * biweight * biweight;
      weight_k[j] = w;
      const LaneDirection d = DirectionOf<kPerLane>(directions, k, j);
      AddSample(sums, j, w * v[j], b[j], d.x, d.y, d.z);
    }
  }
  *eq = sums;
}

PHOTORIG_PS_MULTIVERSION
void WeightsAndNormalEquations(bool per_lane, int lights, const double* directions, const double* observed,
                               const double* inverse_variance, const double* inverse_sigma, const double* residual,
                               const double* inverse_spread, const double* cauchy, const double* huber,
                               const double* tukey, double* weight, LaneNormalEquations* eq) {
  if (per_lane)
    WeightsAndNormalEquationsOf<true>(lights, directions, observed, inverse_variance, inverse_sigma, residual,
                                      inverse_spread, cauchy, huber, tukey, weight, eq);
  else
    WeightsAndNormalEquationsOf<false>(lights, directions, observed, inverse_variance, inverse_sigma, residual,
                                       inverse_spread, cauchy, huber, tukey, weight, eq);
}

// Sorts every lane's values, [index * kLanes + lane], by a fixed sequence of
// compare-exchanges (a sorting network): the same min and max for all lanes
// at once, without a branch on the data. Introselect on one lane's few dozen
// values mispredicts about every other comparison; this is several times
// faster for the lanes together.
PHOTORIG_PS_MULTIVERSION
void SortLanes(const std::pair<int, int>* exchanges, int count, double* values) {
  for (int e = 0; e < count; ++e) {
    double* low = values + exchanges[e].first * kLanes;
    double* high = values + exchanges[e].second * kLanes;
#pragma omp simd
    for (int j = 0; j < kLanes; ++j) {
      const double a = low[j], b = high[j];
      low[j] = std::min(a, b);
      high[j] = std::max(a, b);
    }
  }
}

// Batcher's odd-even merge sort for n values: the network for the next power
// of two, without the exchanges whose upper index is n or beyond (those hold
// +infinity, which such an exchange leaves in place).
std::vector<std::pair<int, int>> SortingNetwork(int n) {
  int size = 1;
  while (size < n) size *= 2;
  std::vector<std::pair<int, int>> exchanges;
  for (int p = 1; p < size; p *= 2)
    for (int k = p; k >= 1; k /= 2)
      for (int j = k % p; j + k < size; j += 2 * k)
        for (int i = 0; i < std::min(k, size - j - k); ++i)
          if ((i + j) / (2 * p) == (i + j + k) / (2 * p) && i + j + k < n) exchanges.emplace_back(i + j, i + j + k);
  return exchanges;
}

}  // namespace

double TwiceLoss(RobustOptions::Loss loss, double u) {
  const double u2 = u * u;
  switch (loss) {
    case RobustOptions::Loss::kCauchy: return kCauchyScale * kCauchyScale * std::log1p(u2 / (kCauchyScale * kCauchyScale));
    case RobustOptions::Loss::kHuber:
      return std::abs(u) <= kHuberScale ? u2 : 2.0 * kHuberScale * std::abs(u) - kHuberScale * kHuberScale;
    case RobustOptions::Loss::kTukey: break;
  }
  const double t = 1.0 - std::min(u2 / (kTukeyScale * kTukeyScale), 1.0);
  return kTukeyScale * kTukeyScale / 3.0 * (1.0 - t * t * t);
}

struct RobustLambertianLanes::State {
  LaneVector x;
  LaneNormalEquations equations;
  double chi2[kLanes], used[kLanes];
  double inverse_spread[kLanes], cauchy[kLanes], huber[kLanes], tukey[kLanes];
  int problem[kLanes];  // -1: idle
  int usable[kLanes], iteration[kLanes];
  bool converged[kLanes];  // reports at the next residual pass
};

RobustLambertianLanes::RobustLambertianLanes(const std::vector<Eigen::Vector3d>& light_directions,
                                             const RobustOptions& options)
    : lights_(static_cast<int>(light_directions.size())),
      options_(options),
      directions_(DirectionArray(light_directions)),
      observed_(light_directions.size() * kLanes),
      inverse_variance_(light_directions.size() * kLanes),
      inverse_sigma_(light_directions.size() * kLanes),
      residual_(light_directions.size() * kLanes),
      weight_(light_directions.size() * kLanes),
      magnitude_(light_directions.size() * kLanes),
      sorting_network_(SortingNetwork(lights_)),
      state_(std::make_unique<State>()) {}

RobustLambertianLanes::RobustLambertianLanes(int lights, const RobustOptions& options)
    : RobustLambertianLanes(std::vector<Eigen::Vector3d>(lights, Eigen::Vector3d::Zero()), options) {
  per_lane_directions_ = true;
  directions_.assign(3 * static_cast<std::size_t>(lights) * kLanes, 0.0);
}

RobustLambertianLanes::~RobustLambertianLanes() = default;
RobustLambertianLanes::RobustLambertianLanes(RobustLambertianLanes&&) noexcept = default;

void RobustLambertianLanes::Load(int lane, const RobustProblem& problem) {
  State& s = *state_;
  int usable = 0;
  for (int k = 0; k < lights_; ++k) {
    const int i = k * kLanes + lane;
    const double inverse_sigma = problem.inverse_sigma[k];
    observed_[i] = problem.observed[k];
    inverse_variance_[i] = inverse_sigma * inverse_sigma;
    inverse_sigma_[i] = inverse_sigma;
    usable += inverse_sigma > 0.0;
  }
  if (per_lane_directions_)
    for (int k = 0; k < lights_; ++k)
      for (int axis = 0; axis < 3; ++axis) directions_[(3 * k + axis) * kLanes + lane] = problem.directions[3 * k + axis];
  for (int i = 0; i < 3; ++i) s.x.v[i][lane] = problem.start[i];
  s.usable[lane] = usable;
  s.iteration[lane] = 0;
  s.converged[lane] = false;
}

void RobustLambertianLanes::Fit(std::span<const RobustProblem> problems, std::span<RobustSolution> solutions) {
  State& s = *state_;
  const int count = static_cast<int>(problems.size());
  // An idle lane fits nothing: no usable samples, its answers ignored.
  auto idle = [&](int lane) {
    for (int k = 0; k < lights_; ++k) {
      const int i = k * kLanes + lane;
      observed_[i] = inverse_variance_[i] = inverse_sigma_[i] = 0.0;
    }
    for (int i = 0; i < 3; ++i) s.x.v[i][lane] = 0.0;
  };
  LaneQueue queue(count);
  auto load = [&](int lane, int index) { Load(lane, problems[index]); };
  auto refill = [&](int lane) { queue.Refill(lane, s.problem, load, idle); };
  for (int lane = 0; lane < kLanes; ++lane) refill(lane);
  while (queue.busy() > 0) {
    Residuals(per_lane_directions_, lights_, directions_.data(), observed_.data(), inverse_variance_.data(), weight_.data(),
              options_.inlier_weight, s.x, residual_.data(), magnitude_.data(), s.chi2, s.used);
    SortLanes(sorting_network_.data(), static_cast<int>(sorting_network_.size()), magnitude_.data());
    bool iterating[kLanes];
    for (int lane = 0; lane < kLanes; ++lane) {
      iterating[lane] = false;
      s.inverse_spread[lane] = std::numeric_limits<double>::infinity();
      s.cauchy[lane] = s.huber[lane] = s.tukey[lane] = 0.0;
      if (s.problem[lane] < 0) continue;
      if (s.converged[lane]) {
        RobustSolution& out = solutions[s.problem[lane]];
        out.x = Eigen::Vector3d(s.x.v[0][lane], s.x.v[1][lane], s.x.v[2][lane]);
        out.used = static_cast<int>(s.used[lane]);
        out.rejected = s.usable[lane] - out.used;
        out.chi2 = s.chi2[lane];
        out.iterations = s.iteration[lane];
        out.ok = out.x.norm() > 0.0 && out.used >= 3;
        refill(lane);  // its residuals come with the next pass
        continue;
      }
      if (s.usable[lane] > 0) {
        const double middle = magnitude_[s.usable[lane] / 2 * kLanes + lane];  // sorted, usable ones first
        s.inverse_spread[lane] = 1.0 / (1.4826 * middle);  // infinite for a zero spread: sigma decides
      }
      const bool warmup = s.iteration[lane] < options_.warmup_iterations;
      const RobustOptions::Loss loss = warmup ? RobustOptions::Loss::kCauchy : options_.loss;
      s.cauchy[lane] = loss == RobustOptions::Loss::kCauchy;
      s.huber[lane] = loss == RobustOptions::Loss::kHuber;
      s.tukey[lane] = loss == RobustOptions::Loss::kTukey;
      iterating[lane] = true;
    }
    WeightsAndNormalEquations(per_lane_directions_, lights_, directions_.data(), observed_.data(), inverse_variance_.data(),
                              inverse_sigma_.data(), residual_.data(), s.inverse_spread, s.cauchy, s.huber, s.tukey,
                              weight_.data(), &s.equations);
    for (int lane = 0; lane < kLanes; ++lane) {
      if (!iterating[lane]) continue;
      const auto& m = s.equations.matrix;
      Eigen::Matrix3d normal_matrix;
      normal_matrix << m[0][lane], m[1][lane], m[2][lane], m[1][lane], m[3][lane], m[4][lane], m[2][lane],
          m[4][lane], m[5][lane];
      const Eigen::LDLT<Eigen::Matrix3d> ldlt(normal_matrix);
      const bool solvable = ldlt.info() == Eigen::Success && ldlt.isPositive() &&
                            ldlt.vectorD().minCoeff() > 1e-12 * ldlt.vectorD().maxCoeff();
      if (!solvable) {
        solutions[s.problem[lane]] = RobustSolution{};
        refill(lane);
        continue;
      }
      const Eigen::Vector3d x(s.x.v[0][lane], s.x.v[1][lane], s.x.v[2][lane]);
      const Eigen::Vector3d step_to =
          ldlt.solve(Eigen::Vector3d(s.equations.rhs[0][lane], s.equations.rhs[1][lane], s.equations.rhs[2][lane]));
      const double step = (step_to - x).norm();
      for (int i = 0; i < 3; ++i) s.x.v[i][lane] = step_to[i];
      const bool warmup = s.iteration[lane] < options_.warmup_iterations;
      ++s.iteration[lane];
      s.converged[lane] = (!warmup && step <= options_.relative_tolerance * step_to.norm()) ||
                          s.iteration[lane] >= options_.max_iterations;
    }
  }
}

}  // namespace photorig::solvers::ps::internal
