#include "photorig/solvers/tomography/ring_filter.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace photorig::solvers::tomography {

bool RingFilterOptions::IsValid(std::string* why) const {
  if (neighbours_px < 1) return core::Refuse(why, "neighbours_px must be >= 1");
  if (!(threshold_sigmas >= 0) || !std::isfinite(threshold_sigmas)) return core::Refuse(why, "threshold_sigmas must be >= 0");
  return true;
}

namespace {

// The median of `values` (reordered); the mean of the middle two for an even count.
double Median(std::vector<double>* values) {
  const std::size_t n = values->size(), half = n / 2;
  std::nth_element(values->begin(), values->begin() + static_cast<std::ptrdiff_t>(half), values->end());
  const double upper = (*values)[half];
  if (n % 2 == 1) return upper;
  return 0.5 * (upper + *std::max_element(values->begin(), values->begin() + static_cast<std::ptrdiff_t>(half)));
}

}  // namespace

RingFilterSummary RemoveStripes(const Geometry& geometry, const RingFilterOptions& options, Absorbance* measurements) {
  solvers::core::SolveTimer timer;
  RingFilterSummary summary;
  if (solvers::core::EndIfInvalid(options, &summary)) return summary;
  std::string why;
  if (!geometry.IsValid(&why)) return timer.End(&summary, solvers::core::Termination::kInvalidInput, why);
  Absorbance& m = *measurements;
  if (m.b.size() != geometry.rays() || (!m.valid.empty() && static_cast<std::int64_t>(m.valid.size()) != geometry.rays()))
    return timer.End(&summary, solvers::core::Termination::kInvalidInput, "the measurements do not match the scan's rays");
  if (geometry.views() < 3)
    return timer.End(&summary, solvers::core::Termination::kFailure,
                     "fewer than three views: a stripe cannot be told from the sample");
  timer.SetupDone(&summary);

  const int cols = geometry.detector_cols, rows = geometry.detector_rows, views = geometry.views();
  auto valid = [&](std::int64_t ray) { return m.valid.empty() || m.valid[static_cast<std::size_t>(ray)] != 0; };
  std::vector<double> offsets(static_cast<std::size_t>(rows) * cols, 0.0), pass_offsets(offsets.size()), neighbours,
      differences;
  // Twice: a stripe next to another biases the first estimate of both.
  for (int pass = 0; pass < 2; ++pass) {
    for (int row = 0; row < rows; ++row)
      for (int col = 0; col < cols; ++col) {
        differences.clear();
        for (int view = 0; view < views; ++view) {
          const std::int64_t ray = geometry.RayIndex(view, row, col);
          if (!valid(ray)) continue;
          neighbours.clear();
          for (int k = 1; k <= options.neighbours_px; ++k)
            for (int c : {col - k, col + k})
              if (c >= 0 && c < cols && valid(geometry.RayIndex(view, row, c)))
                neighbours.push_back(m.b[geometry.RayIndex(view, row, c)]);
          if (neighbours.size() >= 2) differences.push_back(m.b[ray] - Median(&neighbours));
        }
        // Fewer than half the views: too few to tell.
        pass_offsets[static_cast<std::size_t>(row) * cols + col] =
            2 * static_cast<int>(differences.size()) >= views ? Median(&differences) : 0.0;
      }
    // Only offsets beyond the noise of the medians themselves are stripes:
    // subtracting the rest would add rings of that noise.
    std::vector<double> magnitude(pass_offsets.size());
    for (std::size_t i = 0; i < pass_offsets.size(); ++i) magnitude[i] = std::abs(pass_offsets[i]);
    const double spread = 1.4826 * Median(&magnitude);
    for (std::size_t i = 0; i < pass_offsets.size(); ++i)
      if (std::abs(pass_offsets[i]) <= options.threshold_sigmas * spread) pass_offsets[i] = 0.0;
    for (int view = 0; view < views; ++view)
      for (int row = 0; row < rows; ++row)
        for (int col = 0; col < cols; ++col)
          if (const std::int64_t ray = geometry.RayIndex(view, row, col); valid(ray))
            m.b[ray] -= static_cast<float>(pass_offsets[static_cast<std::size_t>(row) * cols + col]);
    for (std::size_t i = 0; i < offsets.size(); ++i) offsets[i] += pass_offsets[i];
  }

  for (double offset : offsets) {
    summary.max_offset = std::max(summary.max_offset, std::abs(offset));
    if (offset != 0.0) ++summary.stripes;
  }
  summary.termination = solvers::core::Termination::kSuccess;
  timer.Finish(&summary);
  return summary;
}

}  // namespace photorig::solvers::tomography
