#include "photorig/solvers/lighting/led_positions.h"
#include "led_dome_scene.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace photorig::solvers::lighting {
namespace {

using testing::DomeCamera;
using testing::ErrorsAgainst;
using testing::LedPositionsMm;
using testing::PositionErrors;
using testing::RenderLedFrames;
using testing::ThreeBalls;

constexpr int kSize = testing::kDomeFrameSize;

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
      EstimateLedPositions(RenderLedFrames(false, ThreeBalls(), truth), DomeCamera(false), ThreeBalls());
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  ASSERT_EQ(summary.leds.size(), truth.size());
  EXPECT_EQ(summary.unusable, 0);
  for (const LedPositionEstimate& led : summary.leds) {
    EXPECT_TRUE(led.usable) << led.note;
    EXPECT_EQ(led.used_spheres.size(), 3u);
  }
  const PositionErrors e = ErrorsAgainst(summary, truth);
  EXPECT_LT(e.mean_mm, 0.5);  // measured: 0.26 mean, 0.42 max
  EXPECT_LT(e.max_mm, 1.0);
}

TEST(LedPositions, ThreeBallsPlaceNearLedsThroughAPinhole) {
  const std::vector<Eigen::Vector3d> truth = LedPositionsMm();
  const LedPositionSummary summary =
      EstimateLedPositions(RenderLedFrames(true, ThreeBalls(), truth), DomeCamera(true), ThreeBalls());
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  EXPECT_EQ(summary.unusable, 0);
  const PositionErrors e = ErrorsAgainst(summary, truth);
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
  std::vector<cv::Mat> frames = RenderLedFrames(false, ThreeBalls(), leds);
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
  std::vector<cv::Mat> pair = RenderLedFrames(false, two, leds);
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

// Balls of 17 px radius in the image make highlights a pixel across, placed
// to no better than the pixel: the rays then fix an LED to about 20 mm, and
// each LED is flagged uncertain, not placed (it had been placed 7 mm off on
// average, four of them beyond twice their predicted sigma).
TEST(LedPositions, HighlightsSmallerThanAPixelLeaveEachLedUncertain) {
  const std::vector<Eigen::Vector3d> truth = LedPositionsMm();
  const MirrorSphereLayout small = ThreeBalls(6.0);
  const LedPositionSummary summary = EstimateLedPositions(RenderLedFrames(false, small, truth), DomeCamera(false), small);
  ASSERT_EQ(summary.leds.size(), truth.size());
  EXPECT_EQ(summary.usable, 0);
  EXPECT_FALSE(summary.IsSolutionUsable());
  for (const LedPositionEstimate& led : summary.leds) {
    EXPECT_FALSE(led.usable);
    EXPECT_TRUE(led.flags & kLedUncertain) << LedFlagsToString(led.flags) << ": " << led.note;
    EXPECT_NE(led.note.find("larger balls"), std::string::npos) << led.note;
  }
  // Balls of 29 px still place every LED, each within twice its predicted sigma.
  const MirrorSphereLayout medium = ThreeBalls(10.0);
  const LedPositionSummary placed = EstimateLedPositions(RenderLedFrames(false, medium, truth), DomeCamera(false), medium);
  EXPECT_EQ(placed.usable, static_cast<int>(truth.size()));
  EXPECT_EQ(ErrorsAgainst(placed, truth).beyond_two_sigma, 0);
}

TEST(LedPositions, AMisplacedBallFlagsItsLedsRaysApart) {
  const std::vector<Eigen::Vector3d> truth = LedPositionsMm();
  const std::vector<cv::Mat> frames = RenderLedFrames(false, ThreeBalls(), truth);
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
