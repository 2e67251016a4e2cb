#include "photorig/sim/camera_model.h"

#include <opencv2/calib3d.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

namespace photorig::sim {

bool CameraModel::IsValid(std::string* why) const {
  auto fail = [why](const char* message) {
    if (why) *why = message;
    return false;
  };
  if (width < 1 || height < 1) return fail("the image needs at least one pixel");
  if (projection == Projection::kOrthographic && !(pixel_pitch_mm > 0)) return fail("pixel_pitch_mm must be > 0");
  if (projection == Projection::kPinhole) {
    if (!(fx > 0 && fy > 0)) return fail("fx and fy must be > 0");
    if (!(distance_mm > 0)) return fail("distance_mm must be > 0");
    for (double k : distortion)
      if (!std::isfinite(k)) return fail("distortion coefficients must be finite");
  }
  return true;
}

void CameraModel::Ray(int col, int row, Eigen::Vector3d* origin, Eigen::Vector3d* direction) const {
  if (projection == Projection::kOrthographic) {
    // Starts high above anything in the scene; only the direction matters.
    *origin = {(col + 0.5 - 0.5 * width) * pixel_pitch_mm, (0.5 * height - row - 0.5) * pixel_pitch_mm, 1e6};
    *direction = {0.0, 0.0, -1.0};
    return;
  }
  *origin = {0.0, 0.0, distance_mm};
  double x = (col + 0.5 - principal_x()) / fx, y = (row + 0.5 - principal_y()) / fy;
  if (std::any_of(distortion.begin(), distortion.end(), [](double k) { return k != 0.0; })) {
    // The lens bends the ray: the pixel sees the undistorted direction.
    // OpenCV puts pixel centres at whole numbers, half a pixel before ours.
    const cv::Matx33d k(fx, 0.0, principal_x() - 0.5, 0.0, fy, principal_y() - 0.5, 0.0, 0.0, 1.0);
    std::vector<cv::Point2d> undistorted;
    cv::undistortPoints(std::vector<cv::Point2d>{{double(col), double(row)}}, undistorted, k,
                        std::vector<double>(distortion.begin(), distortion.end()), cv::noArray(), cv::noArray(),
                        cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-12));
    x = undistorted[0].x, y = undistorted[0].y;
  }
  *direction = Eigen::Vector3d(x, -y, -1.0).normalized();
}

Eigen::Vector3d CameraModel::ViewDirection(const Eigen::Vector3d& point_mm) const {
  if (projection == Projection::kOrthographic) return Eigen::Vector3d::UnitZ();
  return (Eigen::Vector3d(0.0, 0.0, distance_mm) - point_mm).normalized();
}

}  // namespace photorig::sim
