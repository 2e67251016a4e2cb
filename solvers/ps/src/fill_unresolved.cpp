#include "photorig/solvers/ps/fill_unresolved.h"

#include <Eigen/Core>
#include <Eigen/Sparse>

#include <algorithm>
#include <cstdio>
#include <cstdint>
#include <deque>
#include <vector>

namespace photorig::solvers::ps {
namespace {

bool Unresolved(std::uint8_t flag) {
  const auto f = static_cast<PixelFlag>(flag);
  return f == PixelFlag::kTooFewLights || f == PixelFlag::kIllConditioned || f == PixelFlag::kRejectedByModel;
}

std::string CheckMap(const NormalMap& map) {
  if (map.flags.empty() || map.flags.type() != CV_8U) return "the map has no 8-bit flags plane";
  if (map.normals.type() != CV_32FC3 || map.normals.size() != map.flags.size())
    return "the normals must be a 3-channel float image of the flags' size";
  if (map.confidence.type() != CV_32F || map.confidence.size() != map.flags.size())
    return "the confidence must be a float image of the flags' size";
  return {};
}

// Steps from the nearest solved pixel through unresolved ones (4-neighbours),
// up to max_distance; 0 for solved pixels, -1 where out of reach or not
// unresolved.
cv::Mat DistanceFromSolved(const cv::Mat& flags, int max_distance) {
  cv::Mat distance(flags.size(), CV_32S, cv::Scalar(-1));
  std::deque<cv::Point> frontier;
  for (int r = 0; r < flags.rows; ++r)
    for (int c = 0; c < flags.cols; ++c)
      if (flags.at<std::uint8_t>(r, c) == static_cast<std::uint8_t>(PixelFlag::kSolved)) {
        distance.at<int>(r, c) = 0;
        frontier.emplace_back(c, r);
      }
  const cv::Point steps[4] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
  while (!frontier.empty()) {
    const cv::Point p = frontier.front();
    frontier.pop_front();
    const int next = distance.at<int>(p) + 1;
    if (next > max_distance) continue;
    for (const cv::Point& step : steps) {
      const cv::Point q = p + step;
      if (q.x < 0 || q.y < 0 || q.x >= flags.cols || q.y >= flags.rows) continue;
      if (distance.at<int>(q) >= 0 || !Unresolved(flags.at<std::uint8_t>(q))) continue;
      distance.at<int>(q) = next;
      frontier.push_back(q);
    }
  }
  return distance;
}

}  // namespace

bool FillOptions::IsValid(std::string* why) const {
  if (max_distance_px < 1) return core::Refuse(why, "max_distance_px must be at least 1");
  return true;
}

std::string FillSummary::BriefReport() const {
  char text[256];
  std::snprintf(text, sizeof(text), "fill: %s, %zu pixels filled (at most %d px from a solved one, mean confidence %.2f), "
                "%zu left without a normal%s%s",
                core::TerminationName(termination), pixels_filled, max_distance_px, mean_confidence, pixels_left,
                message.empty() ? "" : ": ", message.c_str());
  return text;
}

FillSummary FillUnresolvedNormals(const FillOptions& options, NormalMap* map) {
  core::SolveTimer timer;
  FillSummary summary;
  if (core::EndIfInvalid(options, &summary)) return summary;
  if (core::EndIfBadInput(map ? CheckMap(*map) : "no map", &summary)) return summary;
  const cv::Mat distance = DistanceFromSolved(map->flags, options.max_distance_px);
  // One unknown per reached pixel. Every one has a path of reached pixels to a
  // solved one, so the Laplacian with the solved normals as boundary values
  // is positive definite.
  cv::Mat index(map->flags.size(), CV_32S, cv::Scalar(-1));
  std::vector<cv::Point> unknowns;
  for (int r = 0; r < index.rows; ++r)
    for (int c = 0; c < index.cols; ++c) {
      if (distance.at<int>(r, c) > 0) {
        index.at<int>(r, c) = static_cast<int>(unknowns.size());
        unknowns.emplace_back(c, r);
      } else if (Unresolved(map->flags.at<std::uint8_t>(r, c))) {
        ++summary.pixels_left;
      }
    }
  timer.SetupDone(&summary);
  if (unknowns.empty()) {
    timer.Finish(&summary);
    summary.termination = core::Termination::kSuccess;
    return summary;
  }
  const int n = static_cast<int>(unknowns.size());
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(5 * unknowns.size());
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n, 4);  // normal x, y, z and confidence
  const cv::Point steps[4] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
  for (int u = 0; u < n; ++u) {
    int neighbours = 0;
    for (const cv::Point& step : steps) {
      const cv::Point q = unknowns[u] + step;
      if (q.x < 0 || q.y < 0 || q.x >= index.cols || q.y >= index.rows) continue;
      if (index.at<int>(q) >= 0) {
        triplets.emplace_back(u, index.at<int>(q), -1.0);
        ++neighbours;
      } else if (distance.at<int>(q) == 0) {  // a solved pixel: a boundary value
        const cv::Vec3f& normal = map->normals.at<cv::Vec3f>(q);
        rhs.row(u) += Eigen::Vector4d(normal[0], normal[1], normal[2], map->confidence.at<float>(q));
        ++neighbours;
      }  // outside the mask or out of reach: no constraint (a free boundary)
    }
    triplets.emplace_back(u, u, static_cast<double>(neighbours));
  }
  Eigen::SparseMatrix<double> laplacian(n, n);
  laplacian.setFromTriplets(triplets.begin(), triplets.end());
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(laplacian);
  if (solver.info() != Eigen::Success) {
    summary.End(core::Termination::kFailure, "the interpolation's system could not be factorised");
    return summary;
  }
  const Eigen::MatrixXd values = solver.solve(rhs);
  double confidence_sum = 0.0;
  for (int u = 0; u < n; ++u) {
    const Eigen::Vector3d normal = values.row(u).head<3>().transpose();
    const double length = normal.norm();
    // Opposite normals around a pixel cancel: no direction to give it.
    if (!(length > 1e-6)) {
      ++summary.pixels_left;
      continue;
    }
    const int steps_away = distance.at<int>(unknowns[u]);
    const double confidence = std::clamp(values(u, 3) / steps_away, 0.0, 1.0);
    const Eigen::Vector3f unit = (normal / length).cast<float>();
    map->normals.at<cv::Vec3f>(unknowns[u]) = cv::Vec3f(unit.x(), unit.y(), unit.z());
    map->confidence.at<float>(unknowns[u]) = static_cast<float>(confidence);
    map->flags.at<std::uint8_t>(unknowns[u]) = static_cast<std::uint8_t>(PixelFlag::kFilled);
    ++summary.pixels_filled;
    confidence_sum += confidence;
    summary.max_distance_px = std::max(summary.max_distance_px, steps_away);
  }
  if (summary.pixels_filled > 0) summary.mean_confidence = confidence_sum / static_cast<double>(summary.pixels_filled);
  timer.Finish(&summary);
  summary.termination = core::Termination::kSuccess;
  return summary;
}

}  // namespace photorig::solvers::ps
