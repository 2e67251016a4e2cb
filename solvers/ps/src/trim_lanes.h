#pragma once
// Trimming of a Lambertian fit, many pixels under one set of lights, one
// pixel per SIMD lane: the cheap robust stage of `auto`. Each round solves
// every lane's 3 x 3 weighted normal equations, then one pass over the lights
// computes the residuals and chi-square of every lane; a lane whose fit is
// adequate hands over its answer and takes the next pixel, the others drop the
// samples TrimThreshold picks (rank-one downdates) and go round again. A lane
// that would have to drop more than it may hands over its inadequate fit.

#include <Eigen/Core>

#include <algorithm>
#include <memory>
#include <span>
#include <vector>

namespace photorig::ps::internal {

// One pixel: observed values in solver units for every light, 1 / sigma for
// each (0 marks an unusable sample), and how many samples it may drop.
struct TrimProblem {
  const double* observed = nullptr;
  const double* inverse_sigma = nullptr;
  int max_rejected = 0;
};

struct TrimSolution {
  bool ok = false;             // a finite, non-zero solution on >= 3 samples
  Eigen::Vector3d x = Eigen::Vector3d::Zero();  // albedo / pi times the normal
  double chi2 = 0.0;           // over the kept samples
  int used = 0, rejected = 0;  // kept and trimmed samples
};

// Which samples one trimming round drops, by squared standardised residual u2:
// every sample with u2 >= the returned threshold. A single worst sample goes
// alone (greedy trimming, which refits before judging the next); gross
// outliers, u2 >= gross_u2, go together with every sample within a factor 2
// of the worst residual: a highlight's few samples all leave in one round,
// while a sample that only looks bad because the fit leans towards the
// highlight is judged again after the refit. 0 when nothing stands out.
inline double TrimThreshold(double worst_u2, double gross_u2) {
  return worst_u2 >= gross_u2 ? std::max(gross_u2, worst_u2 / 4.0) : worst_u2;
}

class TrimmedLambertianLanes {
 public:
  // gross_u2: see TrimThreshold.
  TrimmedLambertianLanes(const std::vector<Eigen::Vector3d>& light_directions, double gross_u2);
  ~TrimmedLambertianLanes();
  TrimmedLambertianLanes(TrimmedLambertianLanes&&) noexcept;

  // A fit with dof = used - 3 > 0 is adequate when chi2 <= chi2_quantile[dof];
  // the table must cover the light count.
  void Fit(std::span<const TrimProblem> problems, std::span<const double> chi2_quantile,
           std::span<TrimSolution> solutions);

 private:
  struct State;  // lane registers, in trim_lanes.cpp

  void Load(int lane, const TrimProblem& problem);

  int lights_;
  double gross_u2_;
  std::vector<double> directions_;  // per light: w (3)
  // Struct-of-arrays over lanes: [light * kLanes + lane]; weights are 1 / sigma^2, 0 once trimmed;
  // u2 is the last round's squared standardised residual.
  std::vector<double> observed_, weight_, u2_;
  std::unique_ptr<State> state_;
};

}  // namespace photorig::ps::internal
