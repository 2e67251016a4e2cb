#pragma once
// Lambertian least-squares photometric stereo.
//
// Under a distant light w_k with scale s_k a Lambertian pixel reads
//   I_k - D = s_k * rho * max(0, n . w_k)          (s_k includes the 1/pi)
// so for the lit samples A x = b with A's rows w_k^T, b_k = (I_k - D) / s_k,
// x = rho n. Each sample is read once from memory, in tiles of pixels across
// all K planes, with vector code for AVX2/AVX-512 picked at run time. Plain
// L2 (exclude_unusable_samples = false) applies one 3 x K pseudo-inverse to
// every pixel. Otherwise each pixel is least squares on its own usable
// samples: fully lit pixels get the pseudo-inverse's answer, and pixels with
// shadowed or clipped samples sum their 3 x 3 normal equations over the
// usable ones, solve them in closed form (lanes of pixels at a time) and sum
// their residuals in a second sweep from cache. A tile of mostly shadowed
// pixels goes straight to that kernel. The subset's condition number is
// bounded cheaply and computed exactly only where the bound cannot vouch.
#include "photorig/solvers/ps/stack.h"
#include "photorig/solvers/ps/summary.h"

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

// Fills *result (allocated here). Never throws on bad data: the summary says
// what went wrong and per-pixel flags say which pixels carry no normal.
SolverSummary SolveLambertian(const LambertianOptions& options, const PhotometricStack& stack,
                              NormalMap* result);

}  // namespace photorig::solvers::ps
