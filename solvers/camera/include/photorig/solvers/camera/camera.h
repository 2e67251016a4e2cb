#pragma once
// The camera of a dome in the frame of its LEDs: x right, y up, z towards the
// camera, the sample plane z = 0, millimetres; image rows grow downwards.
//
//   Orthographic: pixel (row r, column c) sees the vertical line through
//     x = (c + 0.5 - W / 2) p, y = (H / 2 - r - 0.5) p (p the pixel pitch).
//   Pinhole: the centre stands on the dome's axis at (0, 0, distance_mm) and
//     looks down -z, image x along +x. Intrinsics and distortion are OpenCV's
//     (calib3d's camera matrix and k1, k2, p1, p2, k3): pixel (r, c) has its
//     centre at (u, v) = (c, r) and sees along (x_n, -y_n, -1), (x_n, y_n) its
//     undistorted normalised coordinates.
//
// Either way a pixel's line of sight is linear in height: the point at height
// z is (x0 + z dx, y0 + z dy, z), which is what PixelRays stores.

#include "photorig/solvers/core/names.h"
#include "photorig/solvers/core/summary.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <array>
#include <optional>
#include <string>
#include <string_view>

namespace photorig::solvers::camera {

enum class Projection { kOrthographic, kPinhole };
inline constexpr core::NameTable<Projection, 2> kProjectionNames = {
    {{Projection::kOrthographic, "orthographic"}, {Projection::kPinhole, "pinhole"}}};
inline const char* ProjectionName(Projection projection) { return core::NameOf(kProjectionNames, projection); }
inline std::optional<Projection> ParseProjection(std::string_view name) { return core::ParseName(kProjectionNames, name); }

// A pinhole camera's intrinsics: focal lengths and principal point in
// pixels, OpenCV's distortion (k1, k2, p1, p2, k3; zero: none), and the
// distance of its centre above the sample plane.
struct PinholeLens {
  double fx_px = 0.0, fy_px = 0.0, cx_px = 0.0, cy_px = 0.0;
  std::array<double, 5> distortion{};
  double distance_mm = 0.0;

  bool IsValid(std::string* why) const;
};

struct Camera {
  Projection projection = Projection::kOrthographic;
  int width_px = 0;
  int height_px = 0;
  double pixel_pitch_mm = 0.0;  // orthographic: the size of a pixel on the object
  PinholeLens pinhole;          // pinhole only

  bool IsValid(std::string* why) const;
  bool IsPinhole() const { return projection == Projection::kPinhole; }
  // The size of a pixel on the sample plane (pinhole: at the image centre).
  double PixelSizeOnPlaneMm() const { return IsPinhole() ? pinhole.distance_mm / pinhole.fx_px : pixel_pitch_mm; }
  // The full angle the image's width spans (0 for orthographic).
  double HorizontalFieldOfViewDeg() const;
  // An orthographic camera with the given pixel pitch.
  static Camera Orthographic(int width_px, int height_px, double pixel_pitch_mm);
};

// Every pixel's line of sight: a pinhole camera's worked out once
// (undistortion is not free), an orthographic camera's from its pixel's
// place (a table of them would cost a solve more than the arithmetic).
class PixelRays {
 public:
  PixelRays() = default;
  // The camera must be valid.
  explicit PixelRays(const Camera& camera);

  const Camera& camera() const { return camera_; }
  // The point of pixel (r, c)'s line of sight at height z_mm.
  Eigen::Vector3d Point(int r, int c, double z_mm) const {
    if (lines_.empty()) return {OrthographicX(c), OrthographicY(r), z_mm};
    const cv::Vec4f& l = lines_.at<cv::Vec4f>(r, c);
    return {l[0] + z_mm * l[2], l[1] + z_mm * l[3], z_mm};
  }
  // Point for pixels (r, c[j]) of one row at heights z_mm[j], j < count, as
  // three float arrays: a batch of pixels without a call per pixel.
  void RowPoints(int r, const int* c, const float* z_mm, int count, float* x, float* y, float* z) const {
    if (lines_.empty()) {
      const float row_y = OrthographicY(r);
      for (int j = 0; j < count; ++j) x[j] = OrthographicX(c[j]), y[j] = row_y, z[j] = z_mm[j];
      return;
    }
    const cv::Vec4f* row = lines_.ptr<cv::Vec4f>(r);
    for (int j = 0; j < count; ++j) {
      const cv::Vec4f& l = row[c[j]];
      const double height = z_mm[j];
      x[j] = static_cast<float>(l[0] + height * l[2]), y[j] = static_cast<float>(l[1] + height * l[3]);
      z[j] = z_mm[j];
    }
  }
  // The unit vector from any point of pixel (r, c)'s line towards the camera.
  Eigen::Vector3d ViewDirection(int r, int c) const {
    if (lines_.empty()) return Eigen::Vector3d::UnitZ();
    const cv::Vec4f& l = lines_.at<cv::Vec4f>(r, c);
    return Eigen::Vector3d(l[2], l[3], 1.0).normalized();
  }
  // ViewDirection of every pixel: CV_32FC3.
  cv::Mat ViewDirections() const;
  // The rays of every step-th pixel of every step-th row from (origin,
  // origin), as the pixels of a camera of their own: its pixel (r, c) is
  // this one's (origin + step r, origin + step c), its pitch or focal
  // lengths scaled so that its neighbours are a step apart (a pinhole's
  // distortion acts on normalised coordinates and stays as it is).
  PixelRays Lattice(int step, int origin) const;
  // The slope of pixel (r, c)'s line: (dx, dy) per mm of height (0 when
  // orthographic); for a pinhole camera -(x_n, -y_n).
  Eigen::Vector2d Slope(int r, int c) const {
    if (lines_.empty()) return Eigen::Vector2d::Zero();
    const cv::Vec4f& l = lines_.at<cv::Vec4f>(r, c);
    return {l[2], l[3]};
  }

 private:
  // An orthographic pixel's place, x right and y up from the image's centre,
  // rounded to float as a table of lines would hold it; pixel (r, c) is the
  // full image's (origin_ + step_ r, origin_ + step_ c).
  float OrthographicX(int c) const {
    return static_cast<float>((origin_ + step_ * c + 0.5 - 0.5 * image_width_px_) * image_pitch_mm_);
  }
  float OrthographicY(int r) const {
    return static_cast<float>((0.5 * image_height_px_ - (origin_ + step_ * r) - 0.5) * image_pitch_mm_);
  }

  Camera camera_;
  cv::Mat lines_;  // pinhole: CV_32FC4, x0, y0, dx, dy; orthographic: empty
  int origin_ = 0, step_ = 1;                            // orthographic: this lattice of the full image
  int image_width_px_ = 0, image_height_px_ = 0;         // orthographic: the full image
  double image_pitch_mm_ = 0.0;
};

}  // namespace photorig::solvers::camera
