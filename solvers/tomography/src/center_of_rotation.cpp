#include "photorig/solvers/tomography/center_of_rotation.h"

#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

namespace photorig::solvers::tomography {

bool CorEstimateOptions::IsValid(std::string* why) const {
  if (!(max_offset_mm >= 0) || !std::isfinite(max_offset_mm)) return core::Refuse(why, "max_offset_mm must be finite and >= 0");
  if (!(pair_tolerance_deg > 0) || !std::isfinite(pair_tolerance_deg)) return core::Refuse(why, "pair_tolerance_deg must be > 0");
  return true;
}

CorEstimateSummary EstimateCorOffset(const Geometry& geometry, const Absorbance& measurements,
                                     const CorEstimateOptions& options) {
  solvers::core::SolveTimer timer;
  CorEstimateSummary summary;
  std::string why;
  if (!options.IsValid(&why)) return timer.End(&summary, solvers::core::Termination::kInvalidOptions, why);
  if (!geometry.IsValid(&why)) return timer.End(&summary, solvers::core::Termination::kInvalidInput, why);
  if (measurements.b.size() != geometry.rays() ||
      (!measurements.valid.empty() && static_cast<std::int64_t>(measurements.valid.size()) != geometry.rays()))
    return timer.End(&summary, solvers::core::Termination::kInvalidInput, "the measurements do not match the scan's rays");
  if (geometry.beam != Beam::kParallel)
    return timer.End(&summary, solvers::core::Termination::kFailure,
                               "the automatic estimate needs a parallel beam (opposite cone-beam views are not mirror images); "
                               "take the offset from the rig configuration");

  // Pairs of views 180 degrees apart.
  const double tolerance = options.pair_tolerance_deg * std::numbers::pi / 180.0;
  std::vector<std::pair<int, int>> pairs;
  for (int i = 0; i < geometry.views(); ++i)
    for (int j = 0; j < geometry.views(); ++j) {
      const double diff = std::remainder(geometry.angles_rad[j] - geometry.angles_rad[i] - std::numbers::pi,
                                         2.0 * std::numbers::pi);
      if (i < j && std::abs(diff) <= tolerance) pairs.emplace_back(i, j);
    }
  if (pairs.empty())
    return timer.End(&summary, solvers::core::Termination::kFailure,
                               "no two views are 180 degrees apart: scan 0..360, or 0..180 including its end view");
  summary.pairs = static_cast<int>(pairs.size());

  const int cols = geometry.detector_cols, rows = geometry.detector_rows;
  const double max_offset = options.max_offset_mm > 0 ? options.max_offset_mm : 0.25 * cols * geometry.pixel_mm;
  // Shift k (whole pixels) stands for an offset of k * pixel / 2.
  const int max_shift = std::min(cols - 2, static_cast<int>(std::ceil(2.0 * max_offset / geometry.pixel_mm)));
  auto valid = [&](std::int64_t ray) { return measurements.valid.empty() || measurements.valid[ray] != 0; };
  std::vector<double> cost(static_cast<std::size_t>(2 * max_shift + 1), std::numeric_limits<double>::infinity());
  for (int k = -max_shift; k <= max_shift; ++k) {
    double sum = 0.0;
    std::int64_t count = 0;
    for (const auto& [i, j] : pairs)
      for (int row = 0; row < rows; ++row)
        for (int col = 0; col < cols; ++col) {
          // Column col of view i meets column cols - 1 - col + k of view j.
          const int mirrored = cols - 1 - col + k;
          if (mirrored < 0 || mirrored >= cols) continue;
          const std::int64_t a = geometry.RayIndex(i, row, col), b = geometry.RayIndex(j, row, mirrored);
          if (!valid(a) || !valid(b)) continue;
          const double d = measurements.b[a] - measurements.b[b];
          sum += d * d;
          ++count;
        }
    // Shifts that overlap less than half the detector compare too little.
    if (count >= static_cast<std::int64_t>(pairs.size()) * rows * cols / 2)
      cost[static_cast<std::size_t>(k + max_shift)] = sum / static_cast<double>(count);
  }
  std::size_t best = 0;
  for (std::size_t i = 1; i < cost.size(); ++i)
    if (cost[i] < cost[best]) best = i;
  if (!std::isfinite(cost[best]))
    return timer.End(&summary, solvers::core::Termination::kFailure, "no shift overlaps enough of the opposing views");
  if (best == 0 || best + 1 == cost.size() || !std::isfinite(cost[best - 1]) || !std::isfinite(cost[best + 1]))
    return timer.End(&summary, solvers::core::Termination::kFailure,
                               "the best match lies at the edge of the search: the offset exceeds max_offset_mm, or the views do not "
                               "mirror each other");
  // Parabola through the minimum and its neighbours.
  const double c0 = cost[best - 1], c1 = cost[best], c2 = cost[best + 1];
  const double curvature = c0 - 2.0 * c1 + c2;
  const double fraction = curvature > 0.0 ? 0.5 * (c0 - c2) / curvature : 0.0;
  const double shift = static_cast<double>(best) - max_shift + fraction;
  summary.offset_mm = 0.5 * shift * geometry.pixel_mm;
  summary.match_rms = std::sqrt(std::max(0.0, c1));
  summary.termination = solvers::core::Termination::kSuccess;
  timer.Finish(&summary);
  return summary;
}

}  // namespace photorig::solvers::tomography
