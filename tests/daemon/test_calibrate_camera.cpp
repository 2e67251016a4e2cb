// photorig calibrate camera end to end: checkerboards the simulator renders
// through a known lens, written as image files, calibrated by the executable
// into a new rig that loads, carries that lens and captures.

#include "../sim/checkerboard_fixtures.h"
#include "photorig/config/rig.h"
#include "test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <string>
#include <vector>

namespace {

using namespace photorig::testing;

// The poses' images as PNG files in `dir`, the flat one first; their paths
// joined by spaces for the command line.
std::string WriteBoards(const TempDir& dir, const std::vector<Eigen::Isometry3d>& poses) {
  std::string paths;
  const std::vector<cv::Mat> images = Render(TrueCamera(), poses);
  for (std::size_t i = 0; i < images.size(); ++i) {
    const std::string path = (dir.path() / ("board" + std::to_string(i) + ".png")).string();
    cv::imwrite(path, images[i]);
    paths += " " + path;
  }
  return paths;
}

const std::string kBaseRig = SourceDir() + "/config/rigs/sim-dome.yaml";

TEST(CalibrateCamera, WritesARigWithTheLensThatLoadsAndCaptures) {
  TempDir dir;
  const std::string images = WriteBoards(dir, Poses());
  const std::string out_rig = (dir.path() / "calibrated.yaml").string();
  const CommandOutcome calibrated =
      Photorig("calibrate camera --images" + images + " --board 9x6 --square-mm 10 --plane-image 0 --rig " +
                   kBaseRig + " --out-rig " + out_rig + " --json",
               dir);
  ASSERT_EQ(calibrated.exit_code, 0) << calibrated.err;
  const nlohmann::json summary = nlohmann::json::parse(calibrated.out);
  EXPECT_EQ(summary["termination"], "success");
  EXPECT_LT(summary["rms_px"].get<double>(), 0.3);
  EXPECT_EQ(summary["out_rig"], out_rig);
  // Every distortion model fitted to the corners, the one of lowest BIC chosen and recorded in the rig.
  EXPECT_EQ(summary["distortion_model"], "k1") << summary["distortion_reason"];
  ASSERT_EQ(summary["candidates"].size(), 5u);
  for (const nlohmann::json& candidate : summary["candidates"])
    EXPECT_GE(candidate["bic"].get<double>(), summary["candidates"][1]["bic"].get<double>()) << candidate.dump();

  const photorig::config::RigConfig rig = photorig::config::LoadRigConfig(out_rig);
  const CameraModel truth = TrueCamera();
  ASSERT_EQ(rig.camera.projection, photorig::solvers::camera::Projection::kPinhole);
  ExpectLensMatches(rig.camera.pinhole, truth);
  const std::string text = ReadText(out_rig);
  EXPECT_NE(text.find("calibration:"), std::string::npos);
  EXPECT_NE(text.find("board0.png"), std::string::npos);
  EXPECT_NE(text.find("distortion_model: k1\n"), std::string::npos) << text;

  const std::string recipe = SourceDir() + "/config/recipes/ps-sphere.yaml";
  EXPECT_EQ(RunPhotorig("run " + recipe + " --rig " + out_rig + " --no-solve --out " + (dir.path() / "run").string(),
                        dir.path() / "run.log"),
            0)
      << ReadText(dir.path() / "run.log");

  // The rig is never overwritten.
  const CommandOutcome again =
      Photorig("calibrate camera --images" + images + " --board 9x6 --square-mm 10 --plane-image 0 --rig " +
                   kBaseRig + " --out-rig " + out_rig,
               dir);
  EXPECT_EQ(again.exit_code, 2) << again.err;
  // A model the calibration does not know is a usage error, naming the ones it does.
  const CommandOutcome unknown =
      Photorig("calibrate camera --images" + images + " --board 9x6 --square-mm 10 --plane-image 0 --rig " +
                   kBaseRig + " --out-rig " + (dir.path() / "other.yaml").string() + " --distortion fisheye",
               dir);
  EXPECT_EQ(unknown.exit_code, 2) << unknown.err;
  EXPECT_NE(unknown.err.find("k1-k2-p1-p2"), std::string::npos) << unknown.err;
}

TEST(CalibrateCamera, TooFewBoardsFailsAndWritesNoRig) {
  TempDir dir;
  std::vector<Eigen::Isometry3d> poses = Poses();
  poses.resize(3);
  poses.push_back(Pose(0, 0, 0, {500, 0, 0}));  // the board out of view
  const std::string images = WriteBoards(dir, poses);
  const std::string out_rig = (dir.path() / "calibrated.yaml").string();
  const CommandOutcome failed =
      Photorig("calibrate camera --images" + images + " --board 9x6 --square-mm 10 --plane-image 0 --rig " +
                   kBaseRig + " --out-rig " + out_rig,
               dir);
  EXPECT_EQ(failed.exit_code, 1);
  EXPECT_NE(failed.err.find("board3.png"), std::string::npos) << failed.err;
  EXPECT_FALSE(std::filesystem::exists(out_rig));
}

}  // namespace
