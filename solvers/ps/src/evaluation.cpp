#include "photorig/solvers/ps/evaluation.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace photorig::solvers::ps {

AngularErrorStats CompareNormals(const cv::Mat& estimate, const cv::Mat& truth, const cv::Mat& mask,
                                 cv::Mat* error_deg) {
  const solvers::core::SolveTimer timer;
  AngularErrorStats stats;
  if (estimate.type() != CV_32FC3 || truth.type() != CV_32FC3 || estimate.size() != truth.size()) {
    stats.End(solvers::core::Termination::kInvalidInput, "both normal maps must be CV_32FC3 of the same size");
    return stats;
  }
  std::vector<double> errors;
  errors.reserve(estimate.total());
  if (error_deg) {
    error_deg->create(estimate.size(), CV_32F);
    error_deg->setTo(std::numeric_limits<float>::quiet_NaN());
  }
  for (int r = 0; r < estimate.rows; ++r) {
    const auto* e = estimate.ptr<cv::Vec3f>(r);
    const auto* t = truth.ptr<cv::Vec3f>(r);
    const std::uint8_t* m = mask.empty() ? nullptr : mask.ptr<std::uint8_t>(r);
    for (int c = 0; c < estimate.cols; ++c) {
      if (m && m[c] == 0) continue;
      const double truth_norm = cv::norm(t[c]);
      if (!std::isfinite(truth_norm) || truth_norm == 0.0) continue;
      ++stats.pixels_with_truth;
      const double estimate_norm = cv::norm(e[c]);
      if (!std::isfinite(estimate_norm) || estimate_norm == 0.0) {
        ++stats.pixels_unresolved;
        continue;
      }
      // atan2 of |cross| and dot keeps precision at small angles, where acos does not.
      const cv::Vec3d a(e[c]), b(t[c]);
      const double angle = std::atan2(cv::norm(a.cross(b)), a.dot(b)) * 180.0 / M_PI;
      errors.push_back(angle);
      if (error_deg) error_deg->at<float>(r, c) = static_cast<float>(angle);
    }
  }
  stats.pixels_evaluated = errors.size();
  if (errors.empty()) {
    // No figure, rather than a perfect 0 deg from no pixels at all.
    stats.mean_deg = stats.median_deg = stats.max_deg = std::numeric_limits<double>::quiet_NaN();
    stats.fraction_under_5deg = stats.fraction_under_10deg = stats.fraction_under_15deg = stats.mean_deg;
    stats.End(solvers::core::Termination::kSuccess, "no pixel has both a normal and a ground truth");
    timer.Finish(&stats);
    return stats;
  }
  double sum = 0.0;
  std::size_t under5 = 0, under10 = 0, under15 = 0;
  for (double angle : errors) {
    sum += angle;
    under5 += angle < 5.0;
    under10 += angle < 10.0;
    under15 += angle < 15.0;
    stats.max_deg = std::max(stats.max_deg, angle);
  }
  const double count = static_cast<double>(errors.size());
  stats.mean_deg = sum / count;
  stats.fraction_under_5deg = under5 / count;
  stats.fraction_under_10deg = under10 / count;
  stats.fraction_under_15deg = under15 / count;
  auto middle = errors.begin() + errors.size() / 2;
  std::nth_element(errors.begin(), middle, errors.end());
  stats.median_deg = *middle;
  if (errors.size() % 2 == 0) {
    stats.median_deg = 0.5 * (stats.median_deg + *std::max_element(errors.begin(), middle));
  }
  stats.End(solvers::core::Termination::kSuccess, "");
  timer.Finish(&stats);
  return stats;
}

}  // namespace photorig::solvers::ps
