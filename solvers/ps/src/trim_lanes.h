#pragma once
// Greedy trimming of a Lambertian fit, many pixels under one set of lights,
// one pixel per SIMD lane: the cheap robust stage of `auto`. Each round solves
// every lane's 3 x 3 weighted normal equations, then one pass over the lights
// computes the residuals, chi-square and the worst sample of every lane; a
// lane whose fit is adequate, or that has trimmed all it may, hands over its
// answer and takes the next pixel, the others drop their worst sample (a
// rank-one downdate) and go round again.

#include <Eigen/Core>

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

class TrimmedLambertianLanes {
 public:
  explicit TrimmedLambertianLanes(const std::vector<Eigen::Vector3d>& light_directions);
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
  std::vector<double> directions_;  // per light: w (3)
  // Struct-of-arrays over lanes: [light * kLanes + lane]; weights are 1 / sigma^2, 0 once trimmed.
  std::vector<double> observed_, weight_;
  std::unique_ptr<State> state_;
};

}  // namespace photorig::ps::internal
