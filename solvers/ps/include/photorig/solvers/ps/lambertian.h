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
#include "photorig/solvers/ps/lambertian_options.h"
#include "photorig/solvers/ps/stack.h"
#include "photorig/solvers/ps/summary.h"

namespace photorig::solvers::ps {

// Fills *result (allocated here). Never throws on bad data: the summary says
// what went wrong and per-pixel flags say which pixels carry no normal.
SolverSummary SolveLambertian(const LambertianOptions& options, const PhotometricStack& stack,
                              NormalMap* result);

}  // namespace photorig::solvers::ps
