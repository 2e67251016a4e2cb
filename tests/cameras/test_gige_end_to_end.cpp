// `photorig run` on the simulated dome with the camera on real GigE Vision:
// the Aravis driver captures from a GigE Vision camera on 127.0.0.1 that
// renders the simulated World. Noise-free, every frame must equal the one the
// in-process simulated camera captures on the same rig (capture only: the
// solvers then see identical input).

#include "../daemon/test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cstdlib>
#include <filesystem>
#include <regex>

namespace {

namespace fs = std::filesystem;
using photorig::testing::ReadText;
using photorig::testing::SourceDir;
using photorig::testing::TempDir;

using photorig::testing::RunPhotorig;

TEST(GigeEndToEnd, SphereCapturedOverGigeVisionMatchesTheSimulatedCamera) {
  TempDir dir;
  const std::string recipe = SourceDir() + "/config/recipes/ps-sphere.yaml";
  const std::string gige_rig = dir.Write("gige.yaml", photorig::testing::NoiseFreeRig(ReadText(SourceDir() + "/config/rigs/sim-dome-gige.yaml")));
  const std::string sim_rig = dir.Write("sim.yaml", photorig::testing::NoiseFreeRig(ReadText(SourceDir() + "/config/rigs/sim-dome.yaml")));
  const fs::path gige_run = dir.path() / "gige", sim_run = dir.path() / "sim";
  ASSERT_EQ(RunPhotorig("run " + recipe + " --rig " + gige_rig + " --no-solve --out " + gige_run.string(), dir.path() / "gige.log"),
            0)
      << ReadText(dir.path() / "gige.log");
  ASSERT_EQ(RunPhotorig("run " + recipe + " --rig " + sim_rig + " --no-solve --out " + sim_run.string(), dir.path() / "sim.log"), 0)
      << ReadText(dir.path() / "sim.log");

  const auto manifest = nlohmann::json::parse(ReadText(gige_run / "manifest.json"));
  EXPECT_EQ(manifest["status"], "complete");
  ASSERT_EQ(manifest["frames"].size(), 49u);
  int compared = 0;
  for (const auto& entry : fs::directory_iterator(sim_run / "frames")) {
    const cv::Mat sim = cv::imread(entry.path().string(), cv::IMREAD_UNCHANGED);
    const cv::Mat gige = cv::imread((gige_run / "frames" / entry.path().filename()).string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(gige.empty()) << entry.path().filename();
    ASSERT_EQ(gige.size(), sim.size());
    EXPECT_EQ(cv::norm(gige, sim, cv::NORM_INF), 0.0) << entry.path().filename();
    ++compared;
  }
  EXPECT_EQ(compared, 49);  // equal frames: the solvers see the same input either way
}

}  // namespace
