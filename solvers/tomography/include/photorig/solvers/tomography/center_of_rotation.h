#pragma once
// The centre-of-rotation offset (Geometry::cor_offset_mm) estimated from the
// data. In a parallel beam the view at theta + 180 degrees is the view at theta
// mirrored about the axis' column:
//   P_{theta+180}(u) = P_theta(2 c - u)
// so the mirrored opposite view matches at a shift of 2c. The estimate sums,
// over every such pair and every detector row, the mean squared difference at
// each whole-pixel shift and refines the best with a parabola.
// A scan needs views 180 degrees apart: 0..360, or 0..180 with its end view
// (EvenAngles(n, 180, true)).

#include "photorig/solvers/core/summary.h"
#include "photorig/solvers/tomography/absorbance.h"
#include "photorig/solvers/tomography/geometry.h"

#include <string>

namespace photorig::solvers::tomography {

struct CorEstimateOptions {
  // Largest |offset| searched, detector mm; 0: a quarter of the detector width.
  double max_offset_mm = 0.0;
  // How far from 180 degrees apart two views may be and still pair. Default 0.01.
  double pair_tolerance_deg = 0.01;

  bool IsValid(std::string* why) const;
};

struct CorEstimateSummary : solvers::core::Summary {
  double offset_mm = 0.0;    // the estimate, in Geometry::cor_offset_mm's convention
  int pairs = 0;             // opposing views used
  double match_rms = 0.0;    // RMS difference of b at the estimate
};

// Ends kFailure (with the reason) for a cone beam, a scan without opposing
// views, or data whose difference curve has no minimum inside the search.
CorEstimateSummary EstimateCorOffset(const Geometry& geometry, const Absorbance& measurements,
                                     const CorEstimateOptions& options = {});

}  // namespace photorig::solvers::tomography
