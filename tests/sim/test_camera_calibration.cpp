// The lens calibration against the simulator: a checkerboard rendered in
// several poses through a known pinhole with distortion, then calibrated.

#include "checkerboard_fixtures.h"
#include "photorig/solvers/camera/calibration.h"

#include <gtest/gtest.h>

#include <iostream>
#include <string>
#include <vector>

namespace {

using namespace photorig::testing;
using photorig::solvers::camera::CalibrateFromCheckerboards;
using photorig::solvers::camera::CheckerboardCalibrationOptions;
using photorig::solvers::core::Termination;

CheckerboardCalibrationOptions Options() {
  CheckerboardCalibrationOptions options;
  options.inner_corners_cols = 9;
  options.inner_corners_rows = 6;
  options.square_mm = 10.0;
  options.plane_image = 0;
  return options;
}

TEST(CameraCalibration, RecoversTheSimulatedLens) {
  const CameraModel truth = TrueCamera();
  const auto summary = CalibrateFromCheckerboards(Options(), Render(truth, Poses()));
  ASSERT_EQ(summary.termination, Termination::kSuccess) << summary.message;
  const auto& lens = summary.lens;
  std::cout << "fx " << lens.fx_px << " fy " << lens.fy_px << " cx " << lens.cx_px << " cy " << lens.cy_px << " k "
            << lens.distortion[0] << " " << lens.distortion[1] << " " << lens.distortion[2] << " " << lens.distortion[3]
            << " " << lens.distortion[4] << " distance " << lens.distance_mm << " mm, rms " << summary.rms_px
            << " px, tilt " << summary.tilt_deg << " deg, fx std " << summary.fx_std_px << " px\n";
  ExpectLensMatches(lens, truth);
  EXPECT_LT(summary.rms_px, 0.3);
  EXPECT_LT(summary.tilt_deg, 0.5);
  EXPECT_EQ(summary.used.size(), Poses().size());
  EXPECT_EQ(summary.image_rms_px.size(), Poses().size());
  EXPECT_TRUE(summary.rejected.empty());
  EXPECT_GT(summary.fx_std_px, 0.0);
  EXPECT_LT(summary.fx_std_px, 0.005 * truth.fx);
}

TEST(CameraCalibration, TooFewBoardsFailsNamingTheImagesWithout) {
  const CameraModel truth = TrueCamera();
  std::vector<Eigen::Isometry3d> poses = Poses();
  poses.resize(3);
  std::vector<cv::Mat> images = Render(truth, poses);
  // The board beyond the field of view: a frame of background only.
  images.push_back(RenderCheckerboard(truth, Board(), Pose(0, 0, 0, {500, 0, 0})));
  const std::vector<std::string> names = {"flat.png", "a.png", "b.png", "empty.png"};
  const auto summary = CalibrateFromCheckerboards(Options(), images, names);
  EXPECT_EQ(summary.termination, Termination::kFailure);
  EXPECT_NE(summary.message.find("empty.png"), std::string::npos) << summary.message;
  EXPECT_NE(summary.message.find("at least 4"), std::string::npos) << summary.message;
  EXPECT_EQ(summary.rejected, std::vector<std::string>{"empty.png"});
}

TEST(CameraCalibration, RefusesATiltedCamera) {
  // The camera tilted 5 deg is the board on the plane tilted 5 deg to it.
  std::vector<Eigen::Isometry3d> poses = Poses();
  poses.resize(5);  // enough for a fit
  poses[0] = Pose(5, 0, 0, {0, 0, 0});
  const auto summary = CalibrateFromCheckerboards(Options(), Render(TrueCamera(), poses));
  EXPECT_EQ(summary.termination, Termination::kFailure);
  EXPECT_NEAR(summary.tilt_deg, 5.0, 0.3);
  EXPECT_NE(summary.message.find("tilted"), std::string::npos) << summary.message;
}

TEST(CameraCalibration, PlaneImageWithoutBoardFails) {
  std::vector<Eigen::Isometry3d> poses = Poses();
  poses.resize(5);
  poses[0] = Pose(0, 0, 0, {500, 0, 0});
  const auto summary = CalibrateFromCheckerboards(Options(), Render(TrueCamera(), poses));
  EXPECT_EQ(summary.termination, Termination::kFailure);
  EXPECT_NE(summary.message.find("plane image"), std::string::npos) << summary.message;
}

TEST(CameraCalibration, RefusesInvalidOptionsAndInput) {
  CheckerboardCalibrationOptions options = Options();
  options.square_mm = 0.0;
  EXPECT_EQ(CalibrateFromCheckerboards(options, {cv::Mat(8, 8, CV_8U)}).termination, Termination::kInvalidOptions);
  options = Options();
  options.plane_image = 2;
  const auto summary = CalibrateFromCheckerboards(options, {cv::Mat(8, 8, CV_8U), cv::Mat(8, 8, CV_8U)});
  EXPECT_EQ(summary.termination, Termination::kInvalidInput);
}

}  // namespace
