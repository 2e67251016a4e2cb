#pragma once
// A second look at the pixels `auto`'s screen could not accept, several
// pixels per SIMD lane set, from the stack's planes or from copies of the
// pixels' samples made while they were in cache: the exact
// adequacy test of the Lambertian pass's fit (chi-square with every sample's
// own variance, where the screen used their average) and, where that fit
// leaves usable samples in attached shadow, one refit without them (FitLit in
// per_pixel_fits.cpp is the same test in double, one pixel at a time).
// On a matte object nearly every doubtful pixel is settled here, so only the
// rest has its samples copied out for the lane fitters.

#include "plane_samples.h"

#include <Eigen/Core>

#include <span>
#include <vector>

namespace photorig::solvers::ps::internal {

struct Recheck {
  // The Lambertian pass's fit x on its usable samples.
  double chi2 = 0.0;
  int used = 0;
  // Set where x leaves `unlit` > 0 usable samples in attached shadow
  // (w . x <= 0), one of them is x's worst misfit, the others are well
  // conditioned, and the refit on them lights exactly those: the refit, its
  // chi-square and sample count.
  bool refitted = false;
  Eigen::Vector3d lit_x = Eigen::Vector3d::Zero();
  double lit_chi2 = 0.0;
  int lit_used = 0, unlit = 0;
};

class RecheckLanes {
 public:
  // Thresholds and the conditioning limit from options; noise from the stack.
  RecheckLanes(const PhotometricStack& stack, const LambertianOptions& options);

  // pixels and x of the same length; any length (taken kFloatLanes at a time).
  // copies: null, or pixel j's samples at copies[j * lights .. + lights) as
  // CopySamples wrote them, read instead of the planes.
  void Check(std::span<const int> pixels, std::span<const Eigen::Vector3d> x, std::span<Recheck> out,
             const float* copies = nullptr) const;
  // Each pixel's sample under each light into out: pixels[j]'s at
  // out[j * lights .. + lights).
  void CopySamples(std::span<const int> pixels, float* out) const;

 private:
  PlaneSamples samples_;
  float max_frobenius_condition2_ = 0.0f;
};

}  // namespace photorig::solvers::ps::internal
