// The lens calibration against the simulator: a checkerboard rendered in
// several poses through a known pinhole with distortion, then calibrated.

#include "checkerboard_fixtures.h"
#include "lens_plane_error.h"
#include "photorig/solvers/camera/calibration.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <iostream>
#include <string>
#include <vector>

namespace {

using namespace photorig::testing;
using photorig::solvers::camera::CalibrateFromCheckerboards;
using photorig::solvers::camera::CheckerboardCalibrationOptions;
using photorig::solvers::camera::DistortionModel;
using photorig::solvers::core::Termination;

// The board of the photographs, flat on the sample plane in the first.
CheckerboardCalibrationOptions Options() {
  const photorig::sim::Checkerboard board = Board();
  CheckerboardCalibrationOptions options;
  options.inner_corners_cols = board.inner_corners_cols;
  options.inner_corners_rows = board.inner_corners_rows;
  options.square_mm = board.square_mm;
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
            << " px, tilt " << summary.tilt_deg << " deg, fx std " << summary.fx_std_px << " px\n"
            << summary.distortion_reason << "\n";
  ExpectLensMatches(lens, truth);
  EXPECT_LT(summary.rms_px, 0.3);
  EXPECT_LT(summary.tilt_deg, 0.5);
  EXPECT_EQ(summary.used.size(), Poses().size());
  EXPECT_EQ(summary.image_rms_px.size(), Poses().size());
  EXPECT_TRUE(summary.rejected.empty());
  EXPECT_GT(summary.fx_std_px, 0.0);
  EXPECT_LT(summary.fx_std_px, 0.005 * truth.fx);
  // The dome's narrow lens bends its corners by k1 alone, as far as 13
  // boards can tell: every model was fitted, and k1 chosen.
  EXPECT_EQ(summary.distortion_model, DistortionModel::kRadial1) << summary.distortion_reason;
  EXPECT_EQ(summary.candidates.size(), 5u);
  EXPECT_EQ(summary.lens.distortion[1], 0.0);
  EXPECT_LT(LensPlaneError(truth, summary.lens).max_px, 1.0);
}

// More coefficients than a lens needs fit the corners' noise and move where
// each pixel looks on the sample plane; fewer than it needs leave its bend.
// The chosen model is the truth's, or one as good on the plane.
TEST(CameraCalibration, ChoosesTheDistortionTheCornersSupport) {
  struct Case {
    std::array<double, 5> distortion;
    std::vector<DistortionModel> acceptable;  // the truth's model, or a simpler one the corners cannot tell from it
    std::vector<DistortionModel> worse;       // fixed models that place the plane's points worse
  };
  const Case cases[] = {
      // A wider lens, decentred: its tangential terms are real.
      // (k3 as well fits it as closely here: it is not chosen, costing a parameter.)
      {{-0.3, 0.12, 0.002, -0.0015, 0.0}, {DistortionModel::kRadial2Tangential}, {DistortionModel::kRadial2}},
      // A distortion-free lens: k1 is as far as noise may take it; tangential
      // terms trade against the principal point.
      {{0.0, 0.0, 0.0, 0.0, 0.0},
       {DistortionModel::kNone, DistortionModel::kRadial1},
       {DistortionModel::kRadial2Tangential, DistortionModel::kRadial3Tangential}},
  };
  for (const Case& c : cases) {
    CameraModel truth = TrueCamera();
    truth.distortion = c.distortion;
    std::vector<Eigen::Isometry3d> poses = Poses();
    poses.resize(9);
    const std::vector<cv::Mat> images = Render(truth, poses);
    const auto chosen = CalibrateFromCheckerboards(Options(), images);
    ASSERT_EQ(chosen.termination, Termination::kSuccess) << chosen.message;
    EXPECT_NE(std::find(c.acceptable.begin(), c.acceptable.end(), chosen.distortion_model), c.acceptable.end())
        << chosen.distortion_reason;
    const double error = LensPlaneError(truth, chosen.lens).max_px;
    EXPECT_LT(error, 0.6) << chosen.distortion_reason;
    for (const DistortionModel fixed : c.worse) {
      CheckerboardCalibrationOptions options = Options();
      options.distortion = fixed;
      const auto forced = CalibrateFromCheckerboards(options, images);
      ASSERT_EQ(forced.candidates.size(), 1u);
      EXPECT_GT(LensPlaneError(truth, forced.lens).max_px, error + 0.2)
          << photorig::solvers::core::NameOf(photorig::solvers::camera::kDistortionModelNames, fixed) << " against "
          << chosen.distortion_reason;
    }
  }
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

// Boards photographed only about the image's centre leave its outer part to
// extrapolation: refused, saying where to put the board.
TEST(CameraCalibration, BoardsThatDoNotReachTheImagesCornersFail) {
  std::vector<Eigen::Isometry3d> poses = Poses();
  poses.resize(5);  // flat and tilted about the centre: enough for a fit, not for the distortion outside
  const auto summary = CalibrateFromCheckerboards(Options(), Render(TrueCamera(), poses));
  EXPECT_EQ(summary.termination, Termination::kFailure);
  EXPECT_NEAR(summary.corner_reach, 0.44, 0.03);
  EXPECT_NE(summary.message.find("the corners found reach 43.9 % of the way"), std::string::npos) << summary.message;
  EXPECT_NE(summary.message.find("near the image's corners"), std::string::npos) << summary.message;
  // The boards moved towards the corners reach far enough.
  poses = Poses();
  poses.resize(9);
  const auto covered = CalibrateFromCheckerboards(Options(), Render(TrueCamera(), poses));
  EXPECT_EQ(covered.termination, Termination::kSuccess) << covered.message;
  EXPECT_GT(covered.corner_reach, 0.7);
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
