#pragma once
// The thresholds and settings of the Lambertian pass (SolveLambertian,
// lambertian.h), which every photometric-stereo method starts from.

#include <limits>
#include <string>

namespace photorig::solvers::ps {

struct LambertianOptions {
  // A sample counts as shadowed when I - D <= shadow_threshold (input units).
  // Default 0: only exact zeros. Set it to a few times the dark noise.
  double shadow_threshold = 0.0;
  // A sample counts as saturated when I >= saturation_level (input units,
  // before dark subtraction). Default: never.
  double saturation_level = std::numeric_limits<double>::infinity();
  // true: solve each pixel on its usable samples only (removes the bias of
  // attached shadows and clipping). false: plain L2 on all samples, the
  // fastest path; pixels are still flagged if fewer than 3 samples are usable.
  bool exclude_unusable_samples = true;
  // Light sets whose 3x3 normal matrix has a condition number (ratio of the
  // largest to the smallest singular value of A) above this are rejected as
  // coplanar. 1e3 loses about three digits of the measurement's precision.
  double max_condition_number = 1e3;
  // 0 = as many threads as OpenMP offers.
  int num_threads = 0;

  bool IsValid(std::string* why) const;
};

}  // namespace photorig::solvers::ps
