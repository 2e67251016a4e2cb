#include "photorig/sim/camera_model.h"

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
  *direction = Eigen::Vector3d((col + 0.5 - principal_x()) / fx, -(row + 0.5 - principal_y()) / fy, -1.0).normalized();
}

Eigen::Vector3d CameraModel::ViewDirection(const Eigen::Vector3d& point_mm) const {
  if (projection == Projection::kOrthographic) return Eigen::Vector3d::UnitZ();
  return (Eigen::Vector3d(0.0, 0.0, distance_mm) - point_mm).normalized();
}

}  // namespace photorig::sim
