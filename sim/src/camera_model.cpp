#include "photorig/sim/camera_model.h"
#include "photorig/sim/camera_rays.h"
#include "photorig/solvers/core/summary.h"

#include <opencv2/calib3d.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

namespace photorig::sim {
using solvers::core::Refuse;

bool CameraModel::IsValid(std::string* why) const {
  if (width < 1 || height < 1) return Refuse(why, "the image needs at least one pixel");
  if (projection == Projection::kOrthographic && !(pixel_pitch_mm > 0)) return Refuse(why, "pixel_pitch_mm must be > 0");
  if (projection == Projection::kPinhole) {
    if (!(fx > 0 && fy > 0)) return Refuse(why, "fx and fy must be > 0");
    if (!(distance_mm > 0)) return Refuse(why, "distance_mm must be > 0");
    for (double k : distortion)
      if (!std::isfinite(k)) return Refuse(why, "distortion coefficients must be finite");
  }
  return true;
}

void CameraModel::Ray(int col, int row, Eigen::Vector3d* origin, Eigen::Vector3d* direction) const {
  std::vector<Eigen::Vector3d> origins, directions;
  CameraRays(*this, {Eigen::Vector2d(col + 0.5, row + 0.5)}, &origins, &directions);
  *origin = origins[0];
  *direction = directions[0];
}

void CameraRays(const CameraModel& camera, const std::vector<Eigen::Vector2d>& points_px,
                std::vector<Eigen::Vector3d>* origins, std::vector<Eigen::Vector3d>* directions) {
  const double fx = camera.fx, fy = camera.fy, pitch_mm = camera.pixel_pitch_mm;
  origins->clear();
  directions->clear();
  if (camera.projection == CameraModel::Projection::kOrthographic) {
    // Starts high above anything in the scene; only the direction matters.
    for (const Eigen::Vector2d& p : points_px) {
      origins->emplace_back((p.x() - 0.5 * camera.width) * pitch_mm, (0.5 * camera.height - p.y()) * pitch_mm, 1e6);
      directions->emplace_back(0.0, 0.0, -1.0);
    }
    return;
  }
  std::vector<cv::Point2d> normalised;
  for (const Eigen::Vector2d& p : points_px)
    normalised.emplace_back((p.x() - camera.principal_x()) / fx, (p.y() - camera.principal_y()) / fy);
  const std::array<double, 5>& distortion = camera.distortion;
  if (std::any_of(distortion.begin(), distortion.end(), [](double k) { return k != 0.0; })) {
    // The lens bends the ray: the point sees the undistorted direction.
    // OpenCV puts pixel centres at whole numbers, half a pixel before ours.
    const cv::Matx33d k(fx, 0.0, camera.principal_x() - 0.5, 0.0, fy, camera.principal_y() - 0.5, 0.0, 0.0, 1.0);
    std::vector<cv::Point2d> distorted;
    for (const Eigen::Vector2d& p : points_px) distorted.emplace_back(p.x() - 0.5, p.y() - 0.5);
    cv::undistortPoints(distorted, normalised, k, std::vector<double>(distortion.begin(), distortion.end()),
                        cv::noArray(), cv::noArray(),
                        cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-12));
  }
  origins->assign(points_px.size(), Eigen::Vector3d(0.0, 0.0, camera.distance_mm));
  for (const cv::Point2d& n : normalised) directions->push_back(Eigen::Vector3d(n.x, -n.y, -1.0).normalized());
}

Eigen::Vector3d CameraModel::ViewDirection(const Eigen::Vector3d& point_mm) const {
  if (projection == Projection::kOrthographic) return Eigen::Vector3d::UnitZ();
  return (Eigen::Vector3d(0.0, 0.0, distance_mm) - point_mm).normalized();
}

}  // namespace photorig::sim
