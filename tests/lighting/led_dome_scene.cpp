#include "led_dome_scene.h"

#include "synthetic_sphere.h"

#include <opencv2/core.hpp>

#include <algorithm>
#include <limits>

namespace photorig::solvers::lighting::testing {
namespace {

constexpr double kPitchMm = 0.35, kFocalPx = 716.55, kDistanceMm = 250.0;
// The LED's highlight lobe: 2 deg wide, as a diffused LED's is.
constexpr double kLobeDeg = 2.0;

}  // namespace

camera::Camera DomeCamera(bool pinhole) {
  camera::Camera camera = camera::Camera::Orthographic(kDomeFrameSize, kDomeFrameSize, kPitchMm);
  if (!pinhole) return camera;
  camera.projection = camera::Projection::kPinhole;
  camera.pinhole = {kFocalPx, kFocalPx, 0.5 * (kDomeFrameSize - 1), 0.5 * (kDomeFrameSize - 1), {}, kDistanceMm};
  return camera;
}

MirrorSphereLayout ThreeBalls(double radius_mm) {
  return {{{-30.0, -20.0, 0.0}, {30.0, -20.0, 0.0}, {0.0, 35.0, 0.0}}, radius_mm};
}

std::vector<Eigen::Vector3d> LedPositionsMm() {
  std::vector<Eigen::Vector3d> positions;
  const std::vector<Eigen::Vector3d> directions = DomeDirections();
  for (std::size_t k = 0; k < directions.size(); k += 4) positions.push_back(250.0 * directions[k]);
  return positions;
}

// The synthetic frame is the dome's: orthographic x = (u + 0.5 - W/2) p; the
// pinhole sits at the origin, so the dome is moved down by its height.
std::vector<cv::Mat> RenderLedFrames(bool pinhole, const MirrorSphereLayout& balls,
                                     const std::vector<Eigen::Vector3d>& leds, double noise_sigma) {
  SyntheticCamera camera;
  camera.pixel_pitch_mm = kPitchMm;
  camera.pinhole = pinhole;
  camera.fx_px = camera.fy_px = kFocalPx;
  camera.cx_px = camera.cy_px = 0.5 * (kDomeFrameSize - 1);
  const Eigen::Vector3d to_camera(0.0, 0.0, pinhole ? -kDistanceMm : 0.0);
  SyntheticImageOptions options;
  options.width = options.height = kDomeFrameSize;
  options.noise_sigma = noise_sigma;
  std::vector<cv::Mat> frames;
  for (std::size_t k = 0; k < leds.size(); ++k) {
    SyntheticLight light;
    light.near = true;
    light.position_mm = leds[k] + to_camera;
    light.angular_sigma_deg = kLobeDeg;
    cv::Mat frame;
    for (std::size_t s = 0; s < balls.centres_mm.size(); ++s) {
      SyntheticSphere ball{balls.centres_mm[s] + to_camera, balls.radius_mm};
      options.seed = static_cast<unsigned>(10 * k + s + 1);
      const cv::Mat image = RenderMirrorSphere(camera, ball, {light}, options);
      frame = frame.empty() ? image : cv::max(frame, image);  // the balls do not overlap in the image
    }
    frames.push_back(frame);
  }
  return frames;
}

PositionErrors ErrorsAgainst(const LedPositionSummary& summary, const std::vector<Eigen::Vector3d>& truth) {
  PositionErrors e;
  int usable = 0;
  for (std::size_t k = 0; k < truth.size(); ++k) {
    if (!summary.leds[k].usable) continue;
    const double error = (summary.leds[k].position_mm - truth[k]).norm();
    e.mean_mm += error;
    e.max_mm = std::max(e.max_mm, error);
    e.beyond_two_sigma += error > 2.0 * summary.leds[k].predicted_sigma_mm ? 1 : 0;
    ++usable;
  }
  if (usable == 0) e.mean_mm = e.max_mm = std::numeric_limits<double>::quiet_NaN();
  else e.mean_mm /= usable;
  return e;
}

}  // namespace photorig::solvers::lighting::testing
