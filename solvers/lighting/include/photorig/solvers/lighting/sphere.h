#pragma once
// A calibration sphere in an image: its silhouette fitted with sub-pixel
// accuracy, and the camera model that maps a pixel to the sphere's surface.
//
// Conventions (as DiLiGenT): camera frame x right, y up, z towards the camera;
// image row 0 is the top; pixel (col, row) has its centre at (u, v) = (col, row).

#include "photorig/solvers/core/names.h"
#include "photorig/solvers/core/summary.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace photorig::solvers::lighting {

struct Circle {
  double cx_px = 0.0;
  double cy_px = 0.0;
  double radius_px = 0.0;
};

struct CameraModel {
  enum class Projection { kOrthographic, kPinhole };
  static constexpr core::NameTable<Projection, 2> kProjectionNames = {
      {{Projection::kOrthographic, "orthographic"}, {Projection::kPinhole, "pinhole"}}};
  Projection projection = Projection::kOrthographic;
  // Pinhole intrinsics (ignored for orthographic): focal lengths and principal point in pixels.
  double fx_px = 0.0;
  double fy_px = 0.0;
  double cx_px = 0.0;
  double cy_px = 0.0;

  bool IsValid(std::string* why) const;
  // Unit ray from the camera into the scene through pixel (u, v). Orthographic: (0, 0, -1).
  Eigen::Vector3d RayDirection(double u, double v) const;
};

struct SphereFitOptions {
  // Grey level separating sphere from background; negative: midway between the
  // 2nd and 98th percentiles of the image.
  double threshold = -1.0;
  double min_radius_px = 5.0;     // smaller blobs are not a sphere
  double outlier_sigma = 3.0;     // edge points further than this many robust sigmas are dropped
  int refinement_rounds = 3;

  bool IsValid(std::string* why) const;
};

struct SphereFitSummary : solvers::core::Summary {
  Circle circle;
  double rms_residual_px = 0.0;    // of the kept edge points from the circle
  double ellipse_axis_ratio = 1.0; // minor / major axis of an ellipse fitted to the same points
  bool touches_border = false;     // silhouette cut by the image border: centre may be biased
  int edge_points_used = 0;
  int edge_points_rejected = 0;
  std::vector<Eigen::Vector2d> edge_points;  // kept sub-pixel silhouette points (u, v)
};

// Fits a circle to the silhouette of the largest bright blob of a single-channel
// image (a mask, or a sphere lit from the front). Edge points are sub-pixel
// threshold crossings along rows and columns; the fit is algebraic then
// geometric with robust trimming.
SphereFitSummary FitSphereSilhouette(const cv::Mat& image, const SphereFitOptions& options = {});

// A sphere placed in the camera frame. Orthographic: the circle is exact and
// the sphere has unit radius in units of radius_px. Pinhole: the silhouette is
// the cone tangent to the sphere; the centre is in units of the sphere radius.
struct SphereGeometry {
  CameraModel camera;
  Circle circle;
  Eigen::Vector3d centre{0.0, 0.0, 0.0};  // pinhole only
  bool valid = false;
  std::string message;
};

// Locates the sphere from its image circle; for a pinhole camera also from the
// silhouette edge points if given (better: the silhouette is an ellipse, not a circle).
SphereGeometry LocateSphere(const CameraModel& camera, const Circle& circle,
                            const std::vector<Eigen::Vector2d>& edge_points = {});

struct SurfacePoint {
  Eigen::Vector3d normal;     // outward unit normal
  Eigen::Vector3d to_camera;  // unit vector from the surface point towards the camera
  Eigen::Vector3d position;   // orthographic: relative to the sphere centre; pinhole: camera frame; radius units
};

// The sphere surface seen through pixel (u, v); false if the ray misses the sphere.
bool SurfaceAt(const SphereGeometry& sphere, double u, double v, SurfacePoint* point);

}  // namespace photorig::solvers::lighting
