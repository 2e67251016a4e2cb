#pragma once
// Ring artefacts: a detector pixel whose response differs from its flat (dust
// on the scintillator, a defective pixel, a flat that drifted) adds the same
// error to b in every view. In the sinogram (angle x column, per detector
// row) that is a stripe along the angles; in the volume a ring about the axis.
//
// RemoveStripes estimates each pixel's offset as the median over the views of
// its difference from the median of its neighbours along the row of the
// view, and subtracts the offsets that stand out from the rest (twice, since
// a stripe beside another biases the first estimate of both). A stripe differs from its
// neighbours in every view by the same amount; the sample's own edges and
// small features pass a given column in only some views, and the median over
// the views ignores them. What does sit on one column in more than half the
// views is taken for a stripe: a feature on the axis itself, or the outline
// of a round sample centred on it. (The mean over the views, the usual
// estimate, would not do: a small feature off the axis leaves sharp horns in
// it at its radius, taken for stripes.)

#include "photorig/solvers/core/summary.h"
#include "photorig/solvers/tomography/absorbance.h"
#include "photorig/solvers/tomography/geometry.h"

#include <string>

namespace photorig::solvers::tomography {

struct RingFilterOptions {
  // Columns either side whose median a pixel is compared with. Default 2: a
  // straight profile gives no difference, a curved one little.
  int neighbours_px = 2;
  // Offsets within this many robust standard deviations (1.4826 x the median
  // |offset|) of them all are the noise of the medians, left alone: a
  // stripe is an outlier among the pixels. Default 3.
  double threshold_sigmas = 3.0;

  bool IsValid(std::string* why) const;
};

struct RingFilterSummary : solvers::core::Summary {
  int stripes = 0;          // pixels (column, row) corrected
  double max_offset = 0.0;  // largest |offset| subtracted (units of b)
};

// Filters *measurements in place (valid rays only; flagged ones stay out).
// Ends kInvalidInput when they do not match the geometry, kFailure with fewer
// than three views (a stripe cannot be told from the sample).
RingFilterSummary RemoveStripes(const Geometry& geometry, const RingFilterOptions& options, Absorbance* measurements);

}  // namespace photorig::solvers::tomography
