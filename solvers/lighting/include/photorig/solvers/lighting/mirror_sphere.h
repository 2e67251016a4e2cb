#pragma once
// Light directions from images of a mirror (chrome) sphere: the highlight's
// normal reflects the view direction into the light direction,
// w_i = 2 (w_o . n) n - w_o.

#include "photorig/solvers/lighting/sphere.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace photorig::solvers::lighting {

// Per-light flags: why an estimate is less trustworthy or unusable.
enum LightFlag : unsigned {
  kLightOk = 0,
  kLightSaturated = 1u << 0,          // centroid of the saturated blob used (informational)
  kLightNearSilhouette = 1u << 1,     // highlight at grazing normal: direction poorly constrained
  kLightMissing = 1u << 2,            // no highlight above the background noise
  kLightMultipleHighlights = 1u << 3, // other bright blobs on the sphere (stray light, two LEDs)
  kLightLargeHighlight = 1u << 4,     // blob too large for a point-like source
  kLightUncertain = 1u << 5,          // predicted uncertainty above HighlightOptions::max_uncertainty_deg
};
std::string LightFlagsToString(unsigned flags);

struct HighlightOptions {
  // Pixel value at or above which a pixel counts as saturated; negative: the
  // image maximum if it is reached by several pixels, otherwise no saturation.
  double saturation_level = -1.0;
  // An unsaturated highlight is the blob above background + fraction * (peak - background).
  double threshold_fraction = 0.5;
  // The peak must exceed the background median by this many robust noise sigmas.
  double min_peak_sigma = 10.0;
  // Highlights whose normal lies closer than this to the silhouette (in degrees
  // of normal angle from 90) are flagged near-silhouette.
  double silhouette_margin_deg = 8.0;
  double max_blob_fraction = 0.02;    // of the sphere's disc area
  double max_uncertainty_deg = 1.0;

  bool IsValid(std::string* why) const;
};

struct LightDirectionEstimate {
  bool usable = false;                     // false when flags make the direction meaningless
  unsigned flags = kLightOk;
  Eigen::Vector3d direction{0, 0, 1};      // unit, camera frame, towards the light
  Eigen::Vector2d highlight_px{0, 0};      // (u, v)
  Eigen::Vector3d normal{0, 0, 1};         // sphere normal at the highlight
  Eigen::Vector3d surface_position{0, 0, 0};  // see SurfacePoint::position
  double blob_area_px = 0.0;
  double peak = 0.0;
  double uncertainty_deg = 0.0;            // one-sigma predicted direction error
  std::string note;
};

// One light from one single-channel image of the mirror sphere.
LightDirectionEstimate EstimateLightDirection(const cv::Mat& image, const SphereGeometry& sphere,
                                              const HighlightOptions& options = {});

// Where a mirror sphere sits when no silhouette image exists (under point
// LEDs a chrome ball shows only its highlights). With an orthographic camera
// each light's highlight lies at (cx + r h_x, cy - r h_y) for the half vector
// h between the view and the light's nominal (design) direction: linear in
// (cx, cy, r), so a least-squares fit over every highlight places the sphere.
// Random errors of the nominal directions average out over many lights; a
// systematic tilt of the whole dome shifts the centre, which the residual
// cannot reveal, so a silhouette or a given circle is preferred when available.
struct HighlightCircleOptions {
  HighlightOptions highlight;       // per-frame highlight search (the whole frame is searched)
  double fixed_radius_px = 0.0;     // > 0: the radius is known (sphere size / pixel pitch); fit the centre only
  double outlier_px = 3.0;          // highlights further than this from the fit are dropped and the fit repeated
  int min_highlights = 3;

  bool IsValid(std::string* why) const;
};

struct HighlightCircleSummary : solvers::core::Summary {
  Circle circle;
  double rms_residual_px = 0.0;     // of the kept highlights from their predicted positions
  int highlights_used = 0;
  std::vector<int> rejected;        // frame indices: no highlight, or an outlier of the fit
};

// `frames[k]` shows the sphere lit by the light whose nominal direction is
// `nominal_directions[k]` (unit, camera frame, towards the light). Orthographic only.
HighlightCircleSummary LocateSphereFromHighlights(const std::vector<cv::Mat>& frames,
                                                  const std::vector<Eigen::Vector3d>& nominal_directions,
                                                  const HighlightCircleOptions& options = {});

// A near light from the reflection rays of two or more spheres (or views):
// the least-squares point closest to every ray. Origins in millimetres.
struct NearLightEstimate {
  bool usable = false;
  Eigen::Vector3d position_mm{0, 0, 0};
  double rms_ray_distance_mm = 0.0;  // how far the rays pass from the point
  std::string message;
};
NearLightEstimate TriangulateNearLight(const std::vector<Eigen::Vector3d>& origins_mm,
                                       const std::vector<Eigen::Vector3d>& directions);

// The reflection point of an estimate in millimetres, camera frame. Orthographic:
// pixel_pitch_mm converts pixels (the sphere centre is at depth 0). Pinhole:
// sphere_radius_mm scales the unit-radius geometry.
Eigen::Vector3d ReflectionPointMm(const SphereGeometry& sphere, const LightDirectionEstimate& estimate,
                                  double pixel_pitch_mm, double sphere_radius_mm);

}  // namespace photorig::solvers::lighting
