#include "photorig/solvers/tomography/geometry.h"
#include "photorig/solvers/core/summary.h"

#include <cmath>
#include <numbers>

namespace photorig::solvers::tomography {

bool Geometry::IsValid(std::string* why) const {
  if (detector_cols < 1 || detector_rows < 1) return core::Refuse(why, "the detector needs at least one column and one row");
  if (!(pixel_mm > 0) || !std::isfinite(pixel_mm)) return core::Refuse(why, "pixel_mm must be finite and > 0");
  if (angles_rad.empty()) return core::Refuse(why, "a scan needs at least one view angle");
  for (double a : angles_rad)
    if (!std::isfinite(a)) return core::Refuse(why, "view angles must be finite");
  if (!std::isfinite(cor_offset_mm)) return core::Refuse(why, "cor_offset_mm must be finite");
  if (beam == Beam::kCone) {
    if (!(source_to_axis_mm > 0) || !std::isfinite(source_to_axis_mm))
      return core::Refuse(why, "a cone beam needs source_to_axis_mm > 0");
    if (!(axis_to_detector_mm >= 0) || !std::isfinite(axis_to_detector_mm))
      return core::Refuse(why, "a cone beam needs axis_to_detector_mm >= 0");
  }
  return true;
}

void Geometry::Ray(int view, int row, int col, Eigen::Vector3d* origin, Eigen::Vector3d* direction) const {
  const double theta = angles_rad[static_cast<std::size_t>(view)];
  const Eigen::Vector3d d(std::cos(theta), std::sin(theta), 0.0), u_hat(-std::sin(theta), std::cos(theta), 0.0),
      z_hat(0.0, 0.0, 1.0);
  const double u = (col + 0.5 - 0.5 * detector_cols) * pixel_mm - cor_offset_mm;
  const double v = (0.5 * detector_rows - row - 0.5) * pixel_mm;
  if (beam == Beam::kParallel) {
    *origin = u * u_hat + v * z_hat;
    *direction = d;
    return;
  }
  const Eigen::Vector3d source = -source_to_axis_mm * d;
  const Eigen::Vector3d pixel = axis_to_detector_mm * d + u * u_hat + v * z_hat;
  *origin = source;
  *direction = (pixel - source).normalized();
}

std::vector<double> EvenAngles(int views, double span_deg, bool include_end) {
  std::vector<double> angles;
  if (views < 1) return angles;
  const double span = span_deg * std::numbers::pi / 180.0;
  const double step = include_end && views > 1 ? span / (views - 1) : span / views;
  for (int i = 0; i < views; ++i) angles.push_back(i * step);
  return angles;
}

}  // namespace photorig::solvers::tomography
