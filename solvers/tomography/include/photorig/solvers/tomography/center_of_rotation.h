#pragma once
// The centre-of-rotation offset (Geometry::cor_offset_mm) estimated from the
// data, two ways.
//
// EstimateCorOffset (opposing views, parallel beam): the view at theta + 180
// degrees is the view at theta mirrored about the axis' column,
//   P_{theta+180}(u) = P_theta(2 c - u),
// so the mirrored opposite view matches at a shift of 2c. The estimate sums,
// over every such pair and every detector row, the mean squared difference at
// each whole-pixel shift and refines the best with a parabola. Its uncertainty
// is the standard error of the same estimate on blocks of detector rows (of
// pairs, or of interleaved columns, where there are too few rows). The rows'
// blocks also give the detector's tilt: the axis' column drifting along the
// rows. A scan needs views 180 degrees apart:
// 0..360, or 0..180 with its end view (EvenAngles(n, 180, true)).
//
// SearchCorOffset (any scan, cone beam too): the held-out-angle residual
// (held_out.h) of a few central detector rows as a function of the offset,
// its minimum bracketed on a coarse grid and refined by golden-section
// search. A wrong centre is a model error the held-out views expose. Slower
// (a reconstruction per candidate), for scans without opposing views.

#include "photorig/solvers/core/summary.h"
#include "photorig/solvers/tomography/absorbance.h"
#include "photorig/solvers/tomography/geometry.h"
#include "photorig/solvers/tomography/held_out.h"

#include <string>

namespace photorig::solvers::tomography {

struct CorEstimateOptions {
  // Largest |offset| searched, detector mm; 0: a quarter of the detector width.
  double max_offset_mm = 0.0;
  // How far from 180 degrees apart two views may be and still pair. Default 0.01.
  double pair_tolerance_deg = 0.01;

  bool IsValid(std::string* why) const;
};

enum class CorMethod { kNone, kOpposingViews, kHeldOutSearch };
const char* CorMethodName(CorMethod method);  // "none", "opposing-views", "held-out-search"

struct CorEstimateSummary : solvers::core::Summary {
  CorMethod method = CorMethod::kNone;
  double offset_mm = 0.0;    // the estimate, in Geometry::cor_offset_mm's convention
  // One standard deviation of the estimate (opposing views: from the blocks; search:
  // the offset at which the held-out residual rises by what its noise resolves).
  double offset_sigma_mm = 0.0;
  // Opposing views: the axis' drift across the detector rows (a detector
  // turned in its plane), atan(d offset / d row) with rows counted
  // downwards, and its standard error; 0 with fewer than 8 rows. The reconstruction does not model it: a tilt that moves the
  // axis by more than offset_sigma_mm over the rows is said in the message.
  double tilt_deg = 0.0;
  double tilt_sigma_deg = 0.0;
  int pairs = 0;             // opposing views used
  double match_rms = 0.0;    // opposing views: RMS difference of b at the estimate
  int candidates = 0;        // search: offsets reconstructed
  double held_out_residual = 0.0;  // search: relative held-out residual at the estimate
};

// Ends kFailure (with the reason) for a cone beam, a scan without opposing
// views, or data whose difference curve has no minimum inside the search.
CorEstimateSummary EstimateCorOffset(const Geometry& geometry, const Absorbance& measurements,
                                     const CorEstimateOptions& options = {});

struct CorSearchOptions {
  // Largest |offset| searched, detector mm; 0: a quarter of the detector width.
  double max_offset_mm = 0.0;
  // The bracket's coarse step; 0: one detector pixel (or 1/16 of the range, if larger).
  double coarse_step_mm = 0.0;
  // Golden-section search ends when the bracket is this narrow. Default 0.05 px.
  double tolerance_px = 0.05;
  // Central detector rows reconstructed per candidate. Default 2: enough
  // signal, and a cone beam's central rows stay near the mid-plane.
  int rows = 2;
  // How each candidate is reconstructed: default SART, 10 passes, no other stop.
  HeldOutOptions held_out = CandidateReconstruction();

  static HeldOutOptions CandidateReconstruction();
  bool IsValid(std::string* why) const;
};

// The offset (absolute, not relative to geometry.cor_offset_mm) minimising
// the held-out residual over [-max, +max]. Ends kFailure when the minimum
// lies at the edge of the range or no candidate could be reconstructed.
CorEstimateSummary SearchCorOffset(const Geometry& geometry, const Absorbance& measurements,
                                   const CorSearchOptions& options = {});

// The offset from opposing views where the scan has them (a parallel beam),
// else (or where their match fails) by the held-out search; the summary's
// method says which, its message why the search was needed.
CorEstimateSummary FindCorOffset(const Geometry& geometry, const Absorbance& measurements,
                                 const CorSearchOptions& options = {});

}  // namespace photorig::solvers::tomography
