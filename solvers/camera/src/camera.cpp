#include "photorig/solvers/camera/camera.h"

#include <opencv2/calib3d.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

namespace photorig::solvers::camera {
namespace {

constexpr double kPi = 3.14159265358979323846;

bool AllFinite(const std::array<double, 5>& values) {
  return std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); });
}

// Undistorted normalised coordinates of every pixel centre, row by row.
// OpenCV's iteration converges to 1e-12 in a few dozen steps for any lens a
// dome uses; its default of five leaves 1e-4 at a wide lens' corners.
std::vector<cv::Point2d> NormalisedCoordinates(const Camera& camera) {
  std::vector<cv::Point2d> pixels;
  pixels.reserve(static_cast<std::size_t>(camera.width_px) * camera.height_px);
  for (int r = 0; r < camera.height_px; ++r)
    for (int c = 0; c < camera.width_px; ++c) pixels.emplace_back(c, r);
  const PinholeLens& lens = camera.pinhole;
  const cv::Matx33d k(lens.fx_px, 0.0, lens.cx_px, 0.0, lens.fy_px, lens.cy_px, 0.0, 0.0, 1.0);
  std::vector<cv::Point2d> normalised;
  cv::undistortPoints(pixels, normalised, k, std::vector<double>(lens.distortion.begin(), lens.distortion.end()),
                      cv::noArray(), cv::noArray(),
                      cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-12));
  return normalised;
}

}  // namespace

bool PinholeLens::IsValid(std::string* why) const {
  if (!(fx_px > 0.0 && fy_px > 0.0) || !std::isfinite(fx_px) || !std::isfinite(fy_px))
    return core::Refuse(why, "a pinhole camera needs focal lengths fx_px, fy_px > 0");
  if (!std::isfinite(cx_px) || !std::isfinite(cy_px)) return core::Refuse(why, "the principal point must be finite");
  if (!AllFinite(distortion)) return core::Refuse(why, "the distortion coefficients must be finite");
  if (!(distance_mm > 0.0) || !std::isfinite(distance_mm))
    return core::Refuse(why, "a pinhole camera needs distance_mm > 0 (its centre above the sample plane)");
  return true;
}

bool Camera::IsValid(std::string* why) const {
  if (width_px < 1 || height_px < 1) return core::Refuse(why, "the image needs at least one pixel");
  if (IsPinhole()) return pinhole.IsValid(why);
  if (!(pixel_pitch_mm > 0.0) || !std::isfinite(pixel_pitch_mm))
    return core::Refuse(why, "an orthographic camera needs pixel_pitch_mm > 0");
  return true;
}

double Camera::HorizontalFieldOfViewDeg() const {
  if (!IsPinhole()) return 0.0;
  // Pixel centres 0 .. W - 1: the image's edges half a pixel beyond.
  return (std::atan((pinhole.cx_px + 0.5) / pinhole.fx_px) + std::atan((width_px - 0.5 - pinhole.cx_px) / pinhole.fx_px)) *
         180.0 / kPi;
}

Camera Camera::Orthographic(int width_px, int height_px, double pixel_pitch_mm) {
  Camera camera;
  camera.width_px = width_px;
  camera.height_px = height_px;
  camera.pixel_pitch_mm = pixel_pitch_mm;
  return camera;
}

PixelRays::PixelRays(const Camera& camera)
    : camera_(camera),
      image_width_px_(camera.width_px),
      image_height_px_(camera.height_px),
      image_pitch_mm_(camera.pixel_pitch_mm) {
  if (!camera.IsPinhole()) return;
  lines_.create(camera.height_px, camera.width_px, CV_32FC4);
  // The line from the centre C = (0, 0, D) along (a, b, -1) with a = x_n,
  // b = -y_n reaches height z at s = D - z: (D a - z a, D b - z b, z).
  const std::vector<cv::Point2d> normalised = NormalisedCoordinates(camera);
  const double d = camera.pinhole.distance_mm;
  for (int r = 0; r < camera.height_px; ++r)
    for (int c = 0; c < camera.width_px; ++c) {
      const cv::Point2d& n = normalised[static_cast<std::size_t>(r) * camera.width_px + c];
      const double a = n.x, b = -n.y;
      lines_.at<cv::Vec4f>(r, c) =
          cv::Vec4f(static_cast<float>(d * a), static_cast<float>(d * b), static_cast<float>(-a), static_cast<float>(-b));
    }
}

cv::Mat PixelRays::ViewDirections() const {
  cv::Mat views(camera_.height_px, camera_.width_px, CV_32FC3);
  for (int r = 0; r < views.rows; ++r)
    for (int c = 0; c < views.cols; ++c) {
      const Eigen::Vector3d v = ViewDirection(r, c);
      views.at<cv::Vec3f>(r, c) = cv::Vec3f(static_cast<float>(v.x()), static_cast<float>(v.y()), static_cast<float>(v.z()));
    }
  return views;
}

PixelRays PixelRays::Lattice(int step, int origin) const {
  PixelRays lattice;
  Camera& camera = lattice.camera_ = camera_;
  camera.width_px = (camera_.width_px - origin + step - 1) / step;
  camera.height_px = (camera_.height_px - origin + step - 1) / step;
  camera.pixel_pitch_mm *= step;
  // Pixel u of this camera is (u - origin) / step of the lattice's.
  camera.pinhole.fx_px /= step, camera.pinhole.fy_px /= step;
  camera.pinhole.cx_px = (camera.pinhole.cx_px - origin) / step;
  camera.pinhole.cy_px = (camera.pinhole.cy_px - origin) / step;
  lattice.origin_ = origin_ + step_ * origin, lattice.step_ = step_ * step;
  lattice.image_width_px_ = image_width_px_, lattice.image_height_px_ = image_height_px_;
  lattice.image_pitch_mm_ = image_pitch_mm_;
  if (lines_.empty()) return lattice;
  lattice.lines_.create(camera.height_px, camera.width_px, CV_32FC4);
  for (int r = 0; r < camera.height_px; ++r)
    for (int c = 0; c < camera.width_px; ++c)
      lattice.lines_.at<cv::Vec4f>(r, c) = lines_.at<cv::Vec4f>(origin + step * r, origin + step * c);
  return lattice;
}

}  // namespace photorig::solvers::camera
