#pragma once
// The quality of a reconstruction without a ground truth: the held-out-angle
// residual. The distinct view angles, sorted, are split in two: the
// even-indexed ones (with every repeat of their angle) are reconstructed, and
// the volume is projected into the odd-indexed ones it never saw:
//   relative residual = ||W_odd sigma_even - b_odd|| / ||b_odd||
// over the valid rays. Noise alone leaves sqrt(sum var(b_odd)) / ||b_odd||
// (noise_floor, when the variance is known); a wrong centre of rotation or
// geometry, too few views, streaks and over-fitted noise all raise it. It
// judges the method and geometry on half the views: the full reconstruction
// has twice as many and is at least as good.
//
// With track_iterations the residual is taken after every iteration: its
// minimum is where the iterations stop fitting the scan and start fitting
// the noise, a stopping point that needs no noise estimate (the pipeline's
// stopping rule for scans without two flats and two darks).

#include "photorig/solvers/core/summary.h"
#include "photorig/solvers/tomography/absorbance.h"
#include "photorig/solvers/tomography/geometry.h"
#include "photorig/solvers/tomography/reconstruct.h"
#include "photorig/solvers/tomography/ray_trace.h"
#include "photorig/solvers/tomography/volume_grid.h"

#include <string>
#include <vector>

namespace photorig::solvers::tomography {

struct HeldOutOptions {
  // How the even views are reconstructed (its progress and on_iteration are
  // called as for any solve). Default: ReconstructOptions' defaults.
  ReconstructOptions reconstruct;
  Interpolation interpolation = Interpolation::kJoseph;
  // Take the held-out residual after every iteration (a forward projection of
  // the odd views each). Off by default.
  bool track_iterations = false;

  bool IsValid(std::string* why) const;
};

struct HeldOutSummary : solvers::core::Summary {
  double relative_residual = 0.0;
  double noise_floor = 0.0;  // sqrt(sum var(b_odd)) / ||b_odd||; 0 when var(b) is unknown
  int fit_views = 0, held_out_views = 0;
  std::int64_t held_out_rays = 0;        // valid rays of the odd views
  // track_iterations: the relative residual after each iteration ([0]: the
  // first), and the iteration (from 1) where it is lowest.
  std::vector<double> residual_history;
  int best_iteration = 0;
  ReconstructionSummary reconstruction;  // of the even views
};

// Ends kFailure with fewer than two distinct angles, or when the even views'
// reconstruction is not usable (its message said); kNoConvergence when that
// reconstruction was (the residual is then of an unconverged volume).
HeldOutSummary HeldOutResidual(const VolumeGrid& grid, const Geometry& geometry, const Absorbance& measurements,
                               const HeldOutOptions& options = {});

// The views of `geometry` at `views` (indices), with their measurements.
void SelectViews(const Geometry& geometry, const Absorbance& measurements, const std::vector<int>& views,
                 Geometry* selected_geometry, Absorbance* selected);

}  // namespace photorig::solvers::tomography
