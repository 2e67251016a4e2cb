// From `photorig run config/recipes/brdf-gonio.yaml` on the simulated
// gonioreflectometer to `photorig solve brdf`: the chosen model is the one the
// simulated material was made from, its parameters within 5 % of the truth.

#include "../daemon/test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
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

TEST(BrdfEndToEnd, NotARunIsAUsageError) {
  TempDir dir;
  EXPECT_EQ(RunPhotorig("solve brdf --run " + dir.path().string(), dir.path() / "solve.log"), 2);
  EXPECT_NE(ReadText(dir.path() / "solve.log").find("manifest.json"), std::string::npos);
}

}  // namespace
