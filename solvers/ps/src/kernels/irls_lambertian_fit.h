#pragma once
// Iteratively reweighted least squares of a Lambertian fit, many pixels under
// one set of lights, one pixel per SIMD lane: the `robust` method, and the
// start of the `blinn-phong` method. Each iteration is two passes over the
// lights shared by all lanes (residuals; then weights and the weighted normal
// equations) with the per-lane steps between them: the median of the
// residuals' magnitudes, the 3 x 3 solve and the convergence test. A lane
// whose fit has converged takes the next pixel at once.
//
// Per pixel, with sigma_k the sample's noise and x the current solution:
//   r_k = b_k - w_k . x,  spread = 1.4826 median |r|  (the residuals' own
//   robust scale: far from the solution the noise alone would make every
//   sample an outlier), u_k = r_k / max(sigma_k, spread), weights from the
//   loss (Cauchy for the first warmup_iterations, to reach the basin of a
//   redescending loss), x = argmin sum weight_k r_k^2 / sigma_k^2; until a
//   step after the warm-up moves x by at most relative_tolerance |x|.

#include "photorig/solvers/ps/photometric_stereo.h"

#include <Eigen/Core>

#include <memory>
#include <span>
#include <utility>
#include <vector>

namespace photorig::solvers::ps::internal {

// One pixel: observed values in solver units for every light, 1 / sigma for
// each (0 marks an unusable sample), the solution to start from, and, for
// lanes made without shared directions, the pixel's own row of every light
// (three per light: its light vector times its irradiance, under near LEDs).
struct RobustProblem {
  const double* observed = nullptr;
  const double* inverse_sigma = nullptr;
  Eigen::Vector3d start = Eigen::Vector3d::Zero();
  const double* directions = nullptr;
};

// Twice the loss of a residual of u sigmas: u^2 near 0, as a chi-square
// term, and bounded (Tukey) or growing slower for outliers; what the IRLS
// fit minimises, for callers that weigh a fit as it weighs its samples.
double TwiceLoss(RobustOptions::Loss loss, double u);

struct RobustSolution {
  bool ok = false;  // false where a weighted system was singular, x = 0, or < 3 inliers remain
  Eigen::Vector3d x = Eigen::Vector3d::Zero();  // albedo / pi times the normal
  double chi2 = 0.0;           // over the inliers (final weight >= inlier_weight)
  int used = 0, rejected = 0;  // usable samples that are inliers, and that are not
  int iterations = 0;
};

class RobustLambertianLanes {
 public:
  RobustLambertianLanes(const std::vector<Eigen::Vector3d>& light_directions, const RobustOptions& options);
  // Lanes whose problems each bring their own directions (RobustProblem::directions).
  RobustLambertianLanes(int lights, const RobustOptions& options);
  ~RobustLambertianLanes();
  RobustLambertianLanes(RobustLambertianLanes&&) noexcept;

  // Fits every problem; solutions[i] answers problems[i].
  void Fit(std::span<const RobustProblem> problems, std::span<RobustSolution> solutions);

 private:
  struct State;  // lane registers, in irls_lambertian_fit.cpp

  void Load(int lane, const RobustProblem& problem);

  int lights_;
  RobustOptions options_;
  // Per light: w (3), shared by every lane; or, with per_lane_directions_,
  // each lane's, [(3 light + axis) * kLanes + lane].
  std::vector<double> directions_;
  bool per_lane_directions_ = false;
  // Struct-of-arrays over lanes, [light * kLanes + lane]: b, 1 / sigma^2 and
  // 1 / sigma (0: unusable), the last residuals and the last weights.
  std::vector<double> observed_, inverse_variance_, inverse_sigma_, residual_, weight_;
  std::vector<double> magnitude_;   // |r| (infinity: unusable), sorted per lane for the median
  std::vector<std::pair<int, int>> sorting_network_;  // compare-exchanges that sort lights_ values
  std::unique_ptr<State> state_;
};

}  // namespace photorig::solvers::ps::internal
