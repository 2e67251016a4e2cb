#pragma once
// Trimming of a Lambertian fit, the cheap robust stage of `auto` (and the
// start of `blinn-phong`), one pixel per float lane. A pixel's raw samples
// are copied out of the stack's planes while the Lambertian pass's tile is
// still in cache, and turned into weighted samples and normal equations in
// one vector pass (CopySamples), so that pixels from several tiles can share
// the lanes. Each round solves every lane's weighted 3 x 3 normal equations,
// then one pass over the lights computes the residuals and chi-square of
// every lane; a lane whose fit is adequate hands over its answer and takes
// the next pixel, the others drop the samples TrimThreshold picks (their
// normal equations summed again over the samples kept) and go round again.
// A lane that would have to drop more than it may hands over its inadequate
// fit. FitTrimmed in per_pixel_fits.cpp is the same stage in double, one
// pixel at a time.

#include "plane_samples.h"

#include <Eigen/Core>

#include <algorithm>
#include <memory>
#include <span>
#include <vector>

namespace photorig::solvers::ps::internal {

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
  // Thresholds from options, noise from the stack (which must outlive this);
  // gross_u2: see TrimThreshold. A pixel may drop at most
  // max_rejected_fraction of its usable samples.
  TrimmedLambertianLanes(const PhotometricStack& stack, const LambertianOptions& options, double gross_u2,
                         double max_rejected_fraction);
  ~TrimmedLambertianLanes();
  TrimmedLambertianLanes(TrimmedLambertianLanes&&) noexcept;

  // A pixel's samples as Fit takes them, row_length() floats: every light's
  // raw value, then the dark frame's (0 without one), then what Fit loads
  // into a lane (the samples in solver units, their weights and their normal
  // equations).
  int row_length() const;
  // values: null, or the pixel's raw values already copied out (one per
  // light), read instead of the planes.
  void CopySamples(int pixel, float* row, const float* values = nullptr) const;

  // rows: one row of row_length() floats per pixel, solutions[i] answers row i.
  // A fit with dof = used - 3 > 0 is adequate when chi2 <= chi2_quantile[dof];
  // the table must cover the light count.
  void Fit(std::span<const float> rows, std::span<const double> chi2_quantile, std::span<TrimSolution> solutions);

 private:
  struct State;  // lane registers, in trimmed_lambertian_fit.cpp

  PlaneSamples samples_;
  double gross_u2_, max_rejected_fraction_;
  // Weights are 1 / sigma^2 in solver units times weight_unit_, which brings
  // the largest possible one to 1: float normal equations then neither
  // overflow nor lose their determinant, whatever the noise level.
  float weight_unit_ = 1.0f;
  // Struct-of-arrays over lanes: [light * kFloatLanes + lane]; b = (I - D) /
  // s, weights (0 once trimmed), and the last round's squared standardised
  // residuals u2.
  std::vector<float> observed_, weight_, u2_;
  std::unique_ptr<State> state_;
};

}  // namespace photorig::solvers::ps::internal
