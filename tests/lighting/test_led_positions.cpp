#include "photorig/solvers/lighting/led_positions.h"
#include "synthetic_sphere.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace photorig::solvers::lighting {
namespace {

using testing::SyntheticCamera;
using testing::SyntheticImageOptions;
using testing::SyntheticLight;
using testing::SyntheticSphere;

// A 384 x 384 camera over a 50 cm dome, as config/rigs/sim-dome-near.yaml:
// orthographic at 0.35 mm per pixel, or a pinhole 250 mm above the plane
// seeing the same 0.35 mm per pixel there.
constexpr int kSize = 384;
constexpr double kPitchMm = 0.35, kFocalPx = 716.55, kDistanceMm = 250.0;
// The LED's highlight lobe: 2 deg wide, as a diffused LED's is.
constexpr double kLobeDeg = 2.0;

camera::Camera DomeCamera(bool pinhole) {
  camera::Camera camera = camera::Camera::Orthographic(kSize, kSize, kPitchMm);
  if (!pinhole) return camera;
  camera.projection = camera::Projection::kPinhole;
  camera.pinhole = {kFocalPx, kFocalPx, 0.5 * (kSize - 1), 0.5 * (kSize - 1), {}, kDistanceMm};
  return camera;
}

// Three 17 mm balls in a triangle, so every LED sees two baselines.
MirrorSphereLayout ThreeBalls() { return {{{-30.0, -20.0, 0.0}, {30.0, -20.0, 0.0}, {0.0, 35.0, 0.0}}, 17.0}; }

// Every fourth LED of a dome of rings on a 250 mm hemisphere.
std::vector<Eigen::Vector3d> LedPositionsMm() {
  std::vector<Eigen::Vector3d> positions;
  const std::vector<Eigen::Vector3d> directions = testing::DomeDirections();
  for (std::size_t k = 0; k < directions.size(); k += 4) positions.push_back(250.0 * directions[k]);
  return positions;
}

// One frame per LED showing every ball, rendered by the tests' own ray tracer
// (the synthetic frame is the dome's: orthographic x = (u + 0.5 - W/2) p; the
// pinhole sits at the origin, so the dome is moved down by its height).
std::vector<cv::Mat> RenderFrames(bool pinhole, const MirrorSphereLayout& balls, const std::vector<Eigen::Vector3d>& leds) {
  SyntheticCamera camera;
  camera.pixel_pitch_mm = kPitchMm;
  camera.pinhole = pinhole;
  camera.fx_px = camera.fy_px = kFocalPx;
  camera.cx_px = camera.cy_px = 0.5 * (kSize - 1);
  const Eigen::Vector3d to_camera(0.0, 0.0, pinhole ? -kDistanceMm : 0.0);
  SyntheticImageOptions options;
  options.width = options.height = kSize;
  options.noise_sigma = 2.0;
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
      const cv::Mat image = testing::RenderMirrorSphere(camera, ball, {light}, options);
      frame = frame.empty() ? image : cv::max(frame, image);  // the balls do not overlap in the image
    }
    frames.push_back(frame);
  }
  return frames;
}

struct Errors {
  double mean_mm = 0.0, max_mm = 0.0;
};

Errors PositionErrors(const LedPositionSummary& summary, const std::vector<Eigen::Vector3d>& truth) {
  Errors e;
  for (std::size_t k = 0; k < truth.size(); ++k) {
    const double error = (summary.leds[k].position_mm - truth[k]).norm();
    e.mean_mm += error / truth.size();
    e.max_mm = std::max(e.max_mm, error);
  }
  return e;
}

// Error budget: the highlight's first moment is good to about 0.01 px here
// (a smooth lobe, each pixel integrated), which on a ball of 49 px radius
// turns the normal by 0.2 mrad and the reflected ray by 0.4 mrad: 0.1 mm
// sideways at 250 mm. Rays that meet at the angle b / L (b the baselines'
// part across the rays, about 60 mm over 250 mm: 0.24 rad) fix the LED along
// them four times worse, 0.4 mm; three balls in a triangle keep b large for
// every LED, where two in a row leave the LEDs on their line with a short one.
TEST(LedPositions, ThreeBallsPlaceNearLedsOrthographic) {
  const std::vector<Eigen::Vector3d> truth = LedPositionsMm();
  const LedPositionSummary summary =
      EstimateLedPositions(RenderFrames(false, ThreeBalls(), truth), DomeCamera(false), ThreeBalls());
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  ASSERT_EQ(summary.leds.size(), truth.size());
  EXPECT_EQ(summary.unusable, 0);
  for (const LedPositionEstimate& led : summary.leds) {
    EXPECT_TRUE(led.usable) << led.note;
    EXPECT_EQ(led.used_spheres.size(), 3u);
  }
  const Errors e = PositionErrors(summary, truth);
  EXPECT_LT(e.mean_mm, 0.5);  // measured: 0.26 mean, 0.42 max
  EXPECT_LT(e.max_mm, 1.0);
}

TEST(LedPositions, ThreeBallsPlaceNearLedsThroughAPinhole) {
  const std::vector<Eigen::Vector3d> truth = LedPositionsMm();
  const LedPositionSummary summary =
      EstimateLedPositions(RenderFrames(true, ThreeBalls(), truth), DomeCamera(true), ThreeBalls());
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  EXPECT_EQ(summary.unusable, 0);
  const Errors e = PositionErrors(summary, truth);
  EXPECT_LT(e.mean_mm, 0.5);  // measured: 0.18 mean, 0.31 max
  EXPECT_LT(e.max_mm, 1.0);
  for (std::size_t k = 0; k < truth.size(); ++k) {
    // The predicted sigma (along the worst axis) covers the error.
    EXPECT_LT((summary.leds[k].position_mm - truth[k]).norm(), 2.0 * summary.leds[k].predicted_sigma_mm);
    EXPECT_LE(summary.leds[k].rms_ray_distance_mm, summary.leds[k].ray_tolerance_mm);
  }
}

TEST(LedPositions, AMissingHighlightLeavesTwoRaysOrFlagsTheLed) {
  const MirrorSphereLayout two{{{-30.0, 0.0, 0.0}, {30.0, 0.0, 0.0}}, 17.0};
  const std::vector<Eigen::Vector3d> leds = {{0.0, 176.777, 176.777}};
  std::vector<cv::Mat> frames = RenderFrames(false, ThreeBalls(), leds);
  // Ball 2's highlight hidden (a finger on the ball, a dead LED's ghost).
  const LedPositionSummary clean = EstimateLedPositions(frames, DomeCamera(false), ThreeBalls());
  const Circle c = clean.sphere_circles[2];
  cv::circle(frames[0], cv::Point(static_cast<int>(c.cx_px), static_cast<int>(c.cy_px)), static_cast<int>(c.radius_px) + 2,
             cv::Scalar(20.0), cv::FILLED);
  const LedPositionSummary three = EstimateLedPositions(frames, DomeCamera(false), ThreeBalls());
  ASSERT_EQ(three.leds.size(), 1u);
  EXPECT_TRUE(three.leds[0].usable) << three.leds[0].note;
  EXPECT_EQ(three.leds[0].used_spheres, (std::vector<int>{0, 1}));
  EXPECT_TRUE(three.leds[0].highlights[2].flags & kLightMissing);
  EXPECT_LT((three.leds[0].position_mm - leds[0]).norm(), 3.0);

  // Two balls, one highlight gone: no position, and the report says why.
  std::vector<cv::Mat> pair = RenderFrames(false, two, leds);
  const Circle left = EstimateLedPositions(pair, DomeCamera(false), two).sphere_circles[0];
  cv::circle(pair[0], cv::Point(static_cast<int>(left.cx_px), static_cast<int>(left.cy_px)),
             static_cast<int>(left.radius_px) + 2, cv::Scalar(20.0), cv::FILLED);
  pair.push_back(cv::Mat());  // and a second LED without a frame at all
  const LedPositionSummary flagged = EstimateLedPositions(pair, DomeCamera(false), two);
  ASSERT_EQ(flagged.leds.size(), 2u);
  EXPECT_EQ(flagged.unusable, 2);
  for (const LedPositionEstimate& led : flagged.leds) {
    EXPECT_FALSE(led.usable);
    EXPECT_TRUE(led.flags & kLedTooFewRays) << LedFlagsToString(led.flags);
  }
  EXPECT_FALSE(flagged.IsSolutionUsable());
}

TEST(LedPositions, AMisplacedBallFlagsItsLedsRaysApart) {
  const std::vector<Eigen::Vector3d> truth = LedPositionsMm();
  const std::vector<cv::Mat> frames = RenderFrames(false, ThreeBalls(), truth);
  // The third ball said to lie 1 mm off where it is: its rays turn by about
  // 2 x 1 / 17 rad and miss the other two by centimetres.
  MirrorSphereLayout told = ThreeBalls();
  told.centres_mm[2].x() += 1.0;
  const LedPositionSummary summary = EstimateLedPositions(frames, DomeCamera(false), told);
  ASSERT_EQ(summary.leds.size(), truth.size());
  int apart = 0;
  for (const LedPositionEstimate& led : summary.leds) apart += (led.flags & kLedRaysApart) ? 1 : 0;
  EXPECT_GT(apart, static_cast<int>(truth.size()) / 2);
}

TEST(LedPositions, RefusesLayoutsAndCamerasItCannotUse) {
  const std::vector<cv::Mat> frames(1, cv::Mat(kSize, kSize, CV_16U, cv::Scalar(20)));
  const auto refusal = [&](const camera::Camera& camera, const MirrorSphereLayout& balls) {
    const LedPositionSummary s = EstimateLedPositions(frames, camera, balls);
    EXPECT_EQ(s.termination, core::Termination::kInvalidInput);
    return s.message;
  };
  EXPECT_NE(refusal(DomeCamera(false), {{{0.0, 0.0, 0.0}}, 17.0}).find("two or more"), std::string::npos);
  EXPECT_NE(refusal(DomeCamera(false), {{{0.0, 0.0, 0.0}, {20.0, 0.0, 0.0}}, 17.0}).find("overlaps"), std::string::npos);
  EXPECT_NE(refusal(DomeCamera(false), {{{-30.0, 0.0, 0.0}, {60.0, 0.0, 0.0}}, 17.0}).find("sphere 1 at"), std::string::npos);
  camera::Camera distorted = DomeCamera(true);
  distorted.pinhole.distortion[0] = -0.1;
  EXPECT_NE(refusal(distorted, ThreeBalls()).find("distortion"), std::string::npos);
  LedPositionOptions options;
  options.ray_tolerance_sigmas = 0.0;
  EXPECT_EQ(EstimateLedPositions(frames, DomeCamera(false), ThreeBalls(), options).termination,
            core::Termination::kInvalidOptions);
}

}  // namespace
}  // namespace photorig::solvers::lighting
