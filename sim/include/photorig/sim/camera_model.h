#pragma once
// The simulated camera's projection. The object frame doubles as the camera
// frame: x right, y up, z towards the camera, millimetres. A pinhole camera
// sits at (0, 0, distance_mm) looking down -z; image rows grow downwards.

#include <Eigen/Core>

#include <array>
#include <string>

namespace photorig::sim {

struct CameraModel {
  enum class Projection { kOrthographic, kPinhole };

  CameraModel() = default;
  // An orthographic camera.
  CameraModel(int width_px, int height_px, double pitch_mm)
      : width(width_px), height(height_px), pixel_pitch_mm(pitch_mm) {}

  int width = 384;
  int height = 384;
  double pixel_pitch_mm = 0.1;  // orthographic: object-space size of one pixel
  Projection projection = Projection::kOrthographic;
  // Pinhole intrinsics in pixels; cx, cy < 0 mean the image centre.
  double fx = 2000.0, fy = 2000.0, cx = -1.0, cy = -1.0;
  double distance_mm = 300.0;  // pinhole: camera centre above the object origin
  // Pinhole: OpenCV's lens distortion k1, k2, p1, p2, k3 (all 0: none).
  std::array<double, 5> distortion{};

  bool IsValid(std::string* why) const;
  // The ray through the centre of pixel (col, row): origin and unit direction.
  void Ray(int col, int row, Eigen::Vector3d* origin, Eigen::Vector3d* direction) const;
  // Unit vector from a surface point towards the camera (w_o).
  Eigen::Vector3d ViewDirection(const Eigen::Vector3d& point_mm) const;
  double principal_x() const { return cx < 0.0 ? 0.5 * width : cx; }
  double principal_y() const { return cy < 0.0 ? 0.5 * height : cy; }
};

}  // namespace photorig::sim
