#pragma once
// Positions of a near-LED dome's LEDs from mirror spheres at known places.
// Each frame shows two or more chrome balls lit by one LED; each ball's
// highlight gives a ray (the reflection point and the reflected direction)
// that passes through the LED, and the rays of all balls are triangulated
// (TriangulateNearLight). The balls' centres are measured, not fitted: a
// mirror ball under point LEDs shows no silhouette, so its image circle is
// the projection of the given centre through the dome's camera.
//
// Frame: the dome's (solvers/camera/camera.h): sample plane z = 0, x right,
// y up as seen from the camera above, millimetres.

#include "photorig/solvers/camera/camera.h"
#include "photorig/solvers/core/summary.h"
#include "photorig/solvers/lighting/mirror_sphere.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace photorig::solvers::lighting {

// The mirror balls of one capture: every ball has the same radius.
struct MirrorSphereLayout {
  std::vector<Eigen::Vector3d> centres_mm;  // dome frame; z = 0 when the ball's equator lies on the sample plane
  double radius_mm = 0.0;
};

struct LedPositionOptions {
  HighlightOptions highlight;  // per-ball highlight search, bounded by the ball's image circle
  // The rays' RMS distance from the triangulated point may be at most
  // max(min_ray_tolerance_mm, ray_tolerance_sigmas x the RMS distance the
  // highlights' predicted uncertainties imply); beyond it the rays do not
  // meet in one LED (a ball misplaced, a stray reflection) and the LED is
  // flagged rays-apart. The prediction is the highlight centre's: its noise,
  // its sampling (a blob narrower than a pixel is placed to a pixel) and a
  // 0.02 px model floor (led_positions.cpp). The floor in mm keeps a
  // prediction that is optimistic (a saturated blob) from flagging a good LED.
  // A position whose predicted error subtends more than
  // highlight.max_uncertainty_deg at the sample is flagged uncertain.
  double ray_tolerance_sigmas = 3.0;
  double min_ray_tolerance_mm = 0.5;

  bool IsValid(std::string* why) const;
};

// Why an LED's position is missing or not trusted.
enum LedFlag : unsigned {
  kLedOk = 0,
  kLedTooFewRays = 1u << 0,    // fewer than two balls show a usable highlight
  kLedRaysApart = 1u << 1,     // the rays pass further apart than the tolerance
  kLedNotTriangulated = 1u << 2,  // the rays are parallel, or the point lies behind a ball
  // The predicted position error subtends more than highlight.max_uncertainty_deg
  // at the sample's centre (balls too small in the image, faint or broad highlights).
  kLedUncertain = 1u << 3,
};
std::string LedFlagsToString(unsigned flags);

struct LedPositionEstimate {
  bool usable = false;  // false: no position may be taken from this LED
  unsigned flags = kLedOk;
  Eigen::Vector3d position_mm{0, 0, 0};  // dome frame; meaningful when rays were triangulated
  double rms_ray_distance_mm = 0.0;       // how far the used rays pass from the position
  double ray_tolerance_mm = 0.0;          // the largest rms_ray_distance_mm accepted (options' rule)
  // One sigma of the position along its worst axis (mostly along the rays),
  // propagated from the highlights' predicted direction uncertainties.
  double predicted_sigma_mm = 0.0;
  // Per ball, in the layout's order; a usable one's centre and uncertainty
  // are the first moment's (see EstimateLedPositions).
  std::vector<LightDirectionEstimate> highlights;
  std::vector<int> used_spheres;                   // balls whose rays were triangulated
  std::string note;
};

struct LedPositionSummary : core::Summary {
  std::vector<Circle> sphere_circles;  // each ball's image circle (bounds its highlight search)
  std::vector<LedPositionEstimate> leds;
  int usable = 0;
  int unusable = 0;
  double mean_rms_ray_distance_mm = 0.0;  // over the usable LEDs
};

// `frames[k]` is the single-channel frame lit by LED k, every ball in it; an
// empty Mat marks a missing frame (that LED is flagged, the others solved).
// The balls must lie apart, below the camera and in its view (else
// kInvalidInput naming the ball). The camera is the dome's: an
// orthographic one, or a pinhole one without distortion (the highlight
// search maps pixels through an ideal pinhole; undistort the frames and give
// zero distortion, else the solve ends kInvalidInput saying so).
LedPositionSummary EstimateLedPositions(const std::vector<cv::Mat>& frames, const camera::Camera& camera,
                                        const MirrorSphereLayout& spheres, const LedPositionOptions& options = {});

}  // namespace photorig::solvers::lighting
