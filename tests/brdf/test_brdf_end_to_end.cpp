// From `photorig run config/recipes/brdf-gonio.yaml` on the simulated
// gonioreflectometer to `photorig solve brdf`: the chosen model is the one the
// simulated material was made from, its parameters within 5 % of the truth.

#include "../daemon/test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <regex>

namespace {

using photorig::testing::ReadText;
using photorig::testing::RunPhotorig;
using photorig::testing::SourceDir;
using photorig::testing::TempDir;

TEST(BrdfEndToEnd, GonioRunFitsTheSimulatedMaterial) {
  TempDir dir;
  // The arms at 20x the rig's simulated speed: the test is about the fit, not the moves.
  const std::string rig = dir.Write(
      "rig.yaml", std::regex_replace(ReadText(SourceDir() + "/config/rigs/sim-gonio.yaml"),
                                     std::regex("time_scale: [0-9.]+"), "time_scale: 200"));
  const std::string run = (dir.path() / "run").string();
  ASSERT_EQ(RunPhotorig("run " + SourceDir() + "/config/recipes/brdf-gonio.yaml --rig " + rig + " --out " + run,
                        dir.path() / "run.log"),
            0)
      << ReadText(dir.path() / "run.log");
  ASSERT_EQ(RunPhotorig("solve brdf --run " + run, dir.path() / "solve.log"), 0) << ReadText(dir.path() / "solve.log");
  const auto report = nlohmann::json::parse(ReadText(dir.path() / "run" / "results" / "brdf" / "report.json"));
  EXPECT_EQ(report["samples"], 40);
  EXPECT_EQ(report["chosen"], "blinn_phong") << report.dump(2);
  EXPECT_TRUE(report["peak_sampled"]);
  // The recipe's material: rho_d 0.4, the simulator's rho_s 0.15 at e = 20,
  // which is k_s = 0.15 / c(20) = 0.50 in the fitted normalisation (docs/brdf.md).
  const auto& fit = report["candidates"][1];
  ASSERT_EQ(fit["model"], "blinn_phong");
  EXPECT_NEAR(fit["diffuse"][0].get<double>(), 0.4, 0.02);
  EXPECT_NEAR(fit["specular"][0].get<double>(), 0.15 / ((20.0 + 4.0) / (4.0 * (std::pow(2.0, -10.0) + 20.0))), 0.025);
  EXPECT_NEAR(fit["shape"].get<double>(), 20.0, 1.0);
  EXPECT_TRUE(fit["lobe_identifiable"]);
}

TEST(BrdfEndToEnd, PlannedPosesPassTheRigsDryRun) {
  TempDir dir;
  const std::string rig = std::filesystem::absolute(SourceDir() + "/config/rigs/sim-gonio.yaml").string();
  // theta_d >= 10 deg keeps the arms 20 deg apart; theta_h + theta_d <= 70 deg keeps them within +-85.
  ASSERT_EQ(RunPhotorig("plan brdf --rig " + rig + " --theta-h 0 30 4 --theta-d 10 40 4", dir.path() / "plan.log"), 0)
      << ReadText(dir.path() / "plan.log");
  const std::string plan = ReadText(dir.path() / "plan.log");
  EXPECT_NE(plan.find("# 16 poses"), std::string::npos) << plan;
  EXPECT_NE(plan.find("# 0 refused"), std::string::npos) << plan;
  std::string steps;
  for (std::size_t start = 0, end; start < plan.size(); start = end + 1) {
    end = plan.find('\n', start);
    if (end == std::string::npos) end = plan.size();
    steps += "    " + plan.substr(start, end - start) + "\n";
  }
  const std::string recipe = dir.Write("planned.yaml", "recipe:\n  name: planned\n  rig: " + rig +
                                                           "\nsample:\n  name: s\n  sim_scene:\n    shape: sample_plane\n"
                                                           "capture:\n  exposure_us: 4000\n  steps:\n" + steps);
  ASSERT_EQ(RunPhotorig("dry-run " + recipe, dir.path() / "dry.log"), 0) << ReadText(dir.path() / "dry.log");
  EXPECT_NE(ReadText(dir.path() / "dry.log").find("16 frames"), std::string::npos) << ReadText(dir.path() / "dry.log");

  // Arms 10 deg apart on a rig that needs 15: refused with the reason, the rest planned.
  ASSERT_EQ(RunPhotorig("plan brdf --rig " + rig + " --theta-h 20 20 1 --theta-d 5 30 2", dir.path() / "close.log"), 0);
  EXPECT_NE(ReadText(dir.path() / "close.log").find("arms 10.00 deg apart, closer than 15.00"), std::string::npos)
      << ReadText(dir.path() / "close.log");
}

TEST(BrdfEndToEnd, NotARunIsAUsageError) {
  TempDir dir;
  EXPECT_EQ(RunPhotorig("solve brdf --run " + dir.path().string(), dir.path() / "solve.log"), 2);
  EXPECT_NE(ReadText(dir.path() / "solve.log").find("manifest.json"), std::string::npos);
}

}  // namespace
