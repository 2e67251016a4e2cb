#pragma once
// Accuracy of a normal map against ground truth, in the terms the
// photometric-stereo literature reports (DiLiGenT: mean angular error).

#include "photorig/solvers/ps/stack.h"
#include "photorig/solvers/core/summary.h"

#include <cstddef>

namespace photorig::solvers::ps {

// kSuccess, or kInvalidInput (maps of other types or sizes; every figure 0).
// Where no pixel has both a normal and a ground truth the figures are NaN.
struct AngularErrorStats : solvers::core::Summary {
  std::size_t pixels_with_truth = 0;   // ground truth defined (finite, non-zero)
  std::size_t pixels_evaluated = 0;    // ... and the estimate has a normal
  std::size_t pixels_unresolved = 0;   // ... but the estimate has none (flagged)
  double mean_deg = 0.0;
  double median_deg = 0.0;
  double max_deg = 0.0;
  double fraction_under_5deg = 0.0;    // of pixels_evaluated
  double fraction_under_10deg = 0.0;
  double fraction_under_15deg = 0.0;
};

// Both maps are CV_32FC3 (x, y, z). Pixels with a non-finite or zero ground
// truth are ignored; `mask` (optional CV_8U) restricts the evaluation further.
// Writes the per-pixel error in degrees into *error_deg when given (NaN where
// undefined).
AngularErrorStats CompareNormals(const cv::Mat& estimate, const cv::Mat& truth,
                                 const cv::Mat& mask = cv::Mat(), cv::Mat* error_deg = nullptr);

}  // namespace photorig::solvers::ps
