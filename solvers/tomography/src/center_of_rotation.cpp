#include "photorig/solvers/tomography/center_of_rotation.h"

#include "photorig/solvers/core/names.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <vector>

namespace photorig::solvers::tomography {

namespace {

constexpr core::NameTable<CorMethod, 3> kCorMethodNames = {{
    {CorMethod::kNone, "none"}, {CorMethod::kOpposingViews, "opposing-views"}, {CorMethod::kHeldOutSearch, "held-out-search"},
}};

}  // namespace

const char* CorMethodName(CorMethod method) { return core::NameOf(kCorMethodNames, method); }

bool CorEstimateOptions::IsValid(std::string* why) const {
  if (!(max_offset_mm >= 0) || !std::isfinite(max_offset_mm)) return core::Refuse(why, "max_offset_mm must be finite and >= 0");
  if (!(pair_tolerance_deg > 0) || !std::isfinite(pair_tolerance_deg)) return core::Refuse(why, "pair_tolerance_deg must be > 0");
  return true;
}

namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

// Sums of squared differences and their counts at each shift.
struct MatchCurve {
  std::vector<double> sum;
  std::vector<std::int64_t> count;
  explicit MatchCurve(std::size_t shifts = 0) : sum(shifts, 0.0), count(shifts, 0) {}
  void Add(const MatchCurve& other, double sign) {
    for (std::size_t k = 0; k < sum.size(); ++k) {
      sum[k] += sign * other.sum[k];
      count[k] += static_cast<std::int64_t>(sign) * other.count[k];
    }
  }
};

// The shift (whole pixels from index 0, with the parabola's fraction) at the
// curve's minimum; NaN where it lies at the edge or the overlap is too thin.
double MinimumShift(const MatchCurve& curve, std::int64_t min_count, double* cost_at_minimum) {
  std::vector<double> cost(curve.sum.size(), kInfinity);
  for (std::size_t k = 0; k < cost.size(); ++k)
    if (curve.count[k] > 0 && curve.count[k] >= min_count) cost[k] = curve.sum[k] / static_cast<double>(curve.count[k]);
  const std::size_t best = static_cast<std::size_t>(std::min_element(cost.begin(), cost.end()) - cost.begin());
  if (!std::isfinite(cost[best]) || best == 0 || best + 1 == cost.size() || !std::isfinite(cost[best - 1]) ||
      !std::isfinite(cost[best + 1]))
    return std::numeric_limits<double>::quiet_NaN();
  const double c0 = cost[best - 1], c1 = cost[best], c2 = cost[best + 1];
  const double curvature = c0 - 2.0 * c1 + c2;
  if (cost_at_minimum) *cost_at_minimum = c1;
  return static_cast<double>(best) + (curvature > 0.0 ? 0.5 * (c0 - c2) / curvature : 0.0);
}

}  // namespace

CorEstimateSummary EstimateCorOffset(const Geometry& geometry, const Absorbance& measurements,
                                     const CorEstimateOptions& options) {
  solvers::core::SolveTimer timer;
  CorEstimateSummary summary;
  summary.method = CorMethod::kOpposingViews;
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
    for (int j = i + 1; j < geometry.views(); ++j) {
      const double diff = std::remainder(geometry.angles_rad[j] - geometry.angles_rad[i] - std::numbers::pi,
                                         2.0 * std::numbers::pi);
      if (std::abs(diff) <= tolerance) pairs.emplace_back(i, j);
    }
  if (pairs.empty())
    return timer.End(&summary, solvers::core::Termination::kFailure,
                               "no two views are 180 degrees apart: scan 0..360, or 0..180 including its end view");
  summary.pairs = static_cast<int>(pairs.size());

  const int cols = geometry.detector_cols, rows = geometry.detector_rows;
  const double max_offset = options.max_offset_mm > 0 ? options.max_offset_mm : 0.25 * cols * geometry.pixel_mm;
  // Shift k (whole pixels) stands for an offset of k * pixel / 2.
  const int max_shift = std::min(cols - 2, static_cast<int>(std::ceil(2.0 * max_offset / geometry.pixel_mm)));
  const auto shifts = static_cast<std::size_t>(2 * max_shift + 1);
  // Blocks for the uncertainty: contiguous rows where there are enough of
  // them (they also give the tilt), else pairs, else interleaved columns.
  constexpr int kMaxBlocks = 16;
  enum class By { kRows, kPairs, kColumns };
  const By by = rows >= 8 ? By::kRows : summary.pairs >= 8 ? By::kPairs : By::kColumns;
  const int blocks = by == By::kRows ? std::min(rows, kMaxBlocks) : by == By::kPairs ? std::min(summary.pairs, kMaxBlocks) : 8;
  std::vector<MatchCurve> block_curve(static_cast<std::size_t>(blocks), MatchCurve(shifts));
  auto valid = [&](std::int64_t ray) { return measurements.valid.empty() || measurements.valid[ray] != 0; };
  for (std::size_t p = 0; p < pairs.size(); ++p) {
    const auto [i, j] = pairs[p];
    for (int row = 0; row < rows; ++row)
      for (int k = -max_shift; k <= max_shift; ++k)
        for (int col = 0; col < cols; ++col) {
          // Column col of view i meets column cols - 1 - col + k of view j.
          const int mirrored = cols - 1 - col + k;
          if (mirrored < 0 || mirrored >= cols) continue;
          const std::int64_t a = geometry.RayIndex(i, row, col), b = geometry.RayIndex(j, row, mirrored);
          if (!valid(a) || !valid(b)) continue;
          const int block = by == By::kRows ? row * blocks / rows : by == By::kPairs ? static_cast<int>(p) % blocks : col % blocks;
          MatchCurve& curve = block_curve[static_cast<std::size_t>(block)];
          const double d = measurements.b[a] - measurements.b[b];
          curve.sum[static_cast<std::size_t>(k + max_shift)] += d * d;
          ++curve.count[static_cast<std::size_t>(k + max_shift)];
        }
  }
  MatchCurve total(shifts);
  for (const MatchCurve& curve : block_curve) total.Add(curve, 1.0);
  // Shifts that overlap less than half the detector compare too little.
  const std::int64_t min_count = static_cast<std::int64_t>(pairs.size()) * rows * cols / 2;
  double cost = 0.0;
  const double shift = MinimumShift(total, min_count, &cost);
  if (std::isnan(shift))
    return timer.End(&summary, solvers::core::Termination::kFailure,
                               "the best match lies at the edge of the search: the offset exceeds max_offset_mm, or the views do not "
                               "mirror each other");
  const double mm_per_shift = 0.5 * geometry.pixel_mm;
  summary.offset_mm = (shift - max_shift) * mm_per_shift;
  summary.match_rms = std::sqrt(std::max(0.0, cost));

  // Each block on its own: their spread is the uncertainty (a
  // leave-one-out jackknife would not do: the whole-pixel minimum jumps).
  std::vector<double> block_shift;
  for (const MatchCurve& curve : block_curve)
    if (const double s = MinimumShift(curve, min_count / blocks / 2, nullptr); !std::isnan(s)) block_shift.push_back(s);
  if (block_shift.size() >= 2) {
    const double n = static_cast<double>(block_shift.size());
    double mean = 0.0, spread = 0.0;
    for (double s : block_shift) mean += s / n;
    for (double s : block_shift) spread += (s - mean) * (s - mean);
    summary.offset_sigma_mm = std::sqrt(spread / (n - 1.0) / n) * mm_per_shift;
  }
  // Tilt: each block of rows on its own, the axis' column against the row.
  if (by == By::kRows) {
    double sw = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
    std::vector<std::pair<double, double>> points;
    for (int block = 0; block < blocks; ++block) {
      const double s = MinimumShift(block_curve[static_cast<std::size_t>(block)], min_count / rows * (rows / blocks), nullptr);
      if (std::isnan(s)) continue;
      const double row_mid = (block + 0.5) * rows / blocks;
      const double offset_px = 0.5 * (s - max_shift);
      points.emplace_back(row_mid, offset_px);
      sw += 1;
      sx += row_mid;
      sy += offset_px;
      sxx += row_mid * row_mid;
      sxy += row_mid * offset_px;
    }
    const double det = sw * sxx - sx * sx;
    if (points.size() >= 3 && det > 0.0) {
      const double slope = (sw * sxy - sx * sy) / det, intercept = (sy - slope * sx) / sw;
      double scatter = 0.0;
      for (const auto& [x, y] : points) scatter += (y - intercept - slope * x) * (y - intercept - slope * x);
      const double slope_sigma = std::sqrt(scatter / (sw - 2.0) * sw / det);
      // Rows run downwards; the tilt is the axis' turn in the detector plane.
      summary.tilt_deg = std::atan(slope) * 180.0 / std::numbers::pi;
      summary.tilt_sigma_deg = slope_sigma * 180.0 / std::numbers::pi;
      const double drift_mm = std::abs(slope) * rows * geometry.pixel_mm;
      if (drift_mm > std::max(summary.offset_sigma_mm, 0.25 * geometry.pixel_mm) &&
          std::abs(slope) > 2.0 * slope_sigma) {
        char text[160];
        std::snprintf(text, sizeof(text),
                      "the detector is tilted by %.2f deg: the axis moves by %.2f px over the rows, which the "
                      "reconstruction does not model",
                      summary.tilt_deg, drift_mm / geometry.pixel_mm);
        summary.message = text;
      }
    }
  }
  summary.termination = solvers::core::Termination::kSuccess;
  timer.Finish(&summary);
  return summary;
}

bool CorSearchOptions::IsValid(std::string* why) const {
  if (!(max_offset_mm >= 0) || !std::isfinite(max_offset_mm)) return core::Refuse(why, "max_offset_mm must be finite and >= 0");
  if (!(coarse_step_mm >= 0) || !std::isfinite(coarse_step_mm)) return core::Refuse(why, "coarse_step_mm must be finite and >= 0");
  if (!(tolerance_px > 0) || !std::isfinite(tolerance_px)) return core::Refuse(why, "tolerance_px must be > 0");
  if (rows < 1) return core::Refuse(why, "rows must be >= 1");
  return held_out.IsValid(why);
}

HeldOutOptions CorSearchOptions::CandidateReconstruction() {
  HeldOutOptions options;
  options.reconstruct.method = Method::kSart;
  options.reconstruct.stop_rule = StopRule::kIterations;
  options.reconstruct.max_iterations = 10;
  options.reconstruct.stagnation_tolerance = 0.0;  // the same passes for every candidate
  return options;
}

CorEstimateSummary SearchCorOffset(const Geometry& geometry, const Absorbance& measurements,
                                   const CorSearchOptions& options) {
  solvers::core::SolveTimer timer;
  CorEstimateSummary summary;
  summary.method = CorMethod::kHeldOutSearch;
  if (solvers::core::EndIfInvalid(options, &summary)) return summary;
  std::string why;
  if (!geometry.IsValid(&why)) return timer.End(&summary, solvers::core::Termination::kInvalidInput, why);
  if (measurements.b.size() != geometry.rays())
    return timer.End(&summary, solvers::core::Termination::kInvalidInput, "the measurements do not match the scan's rays");

  // The central rows (as many as asked, of the detector's parity, so that
  // their centre is the detector's), every view.
  int rows = std::min(options.rows, geometry.detector_rows);
  if ((geometry.detector_rows - rows) % 2 != 0) rows = rows < geometry.detector_rows ? rows + 1 : rows - 1;
  const int first_row = (geometry.detector_rows - rows) / 2;
  Geometry central = geometry;
  central.detector_rows = rows;
  Absorbance data;
  data.b.resize(central.rays());
  if (!measurements.valid.empty()) data.valid.resize(static_cast<std::size_t>(central.rays()));
  if (measurements.variance.size() > 0) data.variance.resize(central.rays());
  for (int view = 0; view < geometry.views(); ++view)
    for (int row = 0; row < rows; ++row)
      for (int col = 0; col < geometry.detector_cols; ++col) {
        const std::int64_t to = central.RayIndex(view, row, col), from = geometry.RayIndex(view, first_row + row, col);
        data.b[to] = measurements.b[from];
        if (!data.valid.empty()) data.valid[static_cast<std::size_t>(to)] = measurements.valid[static_cast<std::size_t>(from)];
        if (data.variance.size() > 0) data.variance[to] = measurements.variance[from];
      }
  // The volume the central rows see: a cone beam's magnified by source / (source + detector distance).
  const double magnification =
      geometry.beam == Beam::kCone ? (geometry.source_to_axis_mm + geometry.axis_to_detector_mm) / geometry.source_to_axis_mm : 1.0;
  const VolumeGrid grid{geometry.detector_cols, geometry.detector_cols, rows, geometry.pixel_mm / magnification};
  timer.SetupDone(&summary);

  HeldOutSummary best_fit;  // of the lowest residual so far
  std::string failure;      // why the last candidate that failed did
  auto residual_at = [&](double offset_mm) {
    central.cor_offset_mm = offset_mm;
    const HeldOutSummary s = HeldOutResidual(grid, central, data, options.held_out);
    ++summary.candidates;
    if (!s.IsSolutionUsable()) {
      failure = s.message;
      return kInfinity;
    }
    if (best_fit.held_out_rays == 0 || s.relative_residual < best_fit.relative_residual) best_fit = s;
    return s.relative_residual;
  };

  const double pixel = geometry.pixel_mm;
  const double max_offset = options.max_offset_mm > 0 ? options.max_offset_mm : 0.25 * geometry.detector_cols * pixel;
  const double step = options.coarse_step_mm > 0 ? options.coarse_step_mm : std::max(pixel, max_offset / 8.0);
  const int half = std::max(1, static_cast<int>(std::ceil(max_offset / step)));
  std::vector<double> coarse;
  for (int i = -half; i <= half; ++i) coarse.push_back(residual_at(i * step));
  const std::size_t best = static_cast<std::size_t>(std::min_element(coarse.begin(), coarse.end()) - coarse.begin());
  if (!std::isfinite(coarse[best]))
    return timer.End(&summary, solvers::core::Termination::kFailure, "no candidate centre could be reconstructed: " + failure);
  if (best == 0 || best + 1 == coarse.size())
    return timer.End(&summary, solvers::core::Termination::kFailure,
                     "the held-out residual is lowest at the edge of the search (" +
                         std::to_string((static_cast<int>(best) - half) * step) +
                         " mm): the offset exceeds max_offset_mm, or the scan does not constrain it");

  // Golden-section search inside the bracket around the coarse minimum.
  const double ratio = (std::sqrt(5.0) - 1.0) / 2.0;
  double lo = (static_cast<int>(best) - half - 1) * step, hi = lo + 2.0 * step;
  double x1 = hi - ratio * (hi - lo), x2 = lo + ratio * (hi - lo);
  double f1 = residual_at(x1), f2 = residual_at(x2);
  while (hi - lo > options.tolerance_px * pixel) {
    if (f1 < f2) {
      hi = x2;
      x2 = x1;
      f2 = f1;
      x1 = hi - ratio * (hi - lo);
      f1 = residual_at(x1);
    } else {
      lo = x1;
      x1 = x2;
      f1 = f2;
      x2 = lo + ratio * (hi - lo);
      f2 = residual_at(x2);
    }
  }
  summary.offset_mm = f1 < f2 ? x1 : x2;
  summary.held_out_residual = std::min(f1, f2);
  // Uncertainty: how far the offset may move before the squared residual
  // rises by its own scatter, sqrt(2 / rays) of it (chi-square), from the
  // coarse curvature.
  const double r0 = coarse[best - 1] * coarse[best - 1], r1 = coarse[best] * coarse[best],
               r2 = coarse[best + 1] * coarse[best + 1];
  const double curvature = (r0 - 2.0 * r1 + r2) / (step * step);
  const double rise = summary.held_out_residual * summary.held_out_residual *
                      std::sqrt(2.0 / static_cast<double>(std::max<std::int64_t>(1, best_fit.held_out_rays)));
  summary.offset_sigma_mm = curvature > 0.0 ? std::sqrt(2.0 * rise / curvature) : kInfinity;
  summary.termination = solvers::core::Termination::kSuccess;
  timer.Finish(&summary);
  return summary;
}

CorEstimateSummary FindCorOffset(const Geometry& geometry, const Absorbance& measurements,
                                 const CorSearchOptions& options) {
  std::string why_search = "a cone beam has no mirrored views";
  if (geometry.beam == Beam::kParallel) {
    CorEstimateOptions opposing;
    opposing.max_offset_mm = options.max_offset_mm;
    const CorEstimateSummary s = EstimateCorOffset(geometry, measurements, opposing);
    if (s.termination == solvers::core::Termination::kSuccess || s.termination == solvers::core::Termination::kInvalidInput)
      return s;
    why_search = s.message;
  }
  CorEstimateSummary s = SearchCorOffset(geometry, measurements, options);
  s.message = "searched by the held-out residual (" + why_search + ")" + (s.message.empty() ? "" : ": " + s.message);
  return s;
}

}  // namespace photorig::solvers::tomography
