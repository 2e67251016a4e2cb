// The near dome's LED intensities and profiles from the led-radiance recipe's
// matte plane, through the executable: `photorig run` then `photorig
// calibrate radiance`, against the simulator's LEDs as built.

#include "photorig/config/rig.h"
#include "test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>

namespace {

namespace fs = std::filesystem;
using photorig::testing::Photorig;
using photorig::testing::ReadText;
using photorig::testing::SourceDir;
using photorig::testing::TempDir;

std::vector<double> ReadColumn(const fs::path& path) {
  std::ifstream in(path);
  std::vector<double> values;
  for (double value; in >> value;) values.push_back(value);
  return values;
}

TEST(LedRadiance, ThePlaneRecipeFindsTheNearDomesIntensitiesAsBuilt) {
  TempDir dir;
  // The dome as built: each LED's irradiance off its stated figure by 5 % RMS.
  const std::string drawing = ReadText(SourceDir() + "/config/rigs/sim-dome-near.yaml");
  const std::string as_built = std::regex_replace(drawing, std::regex("\nsim:\n"), "\nsim:\n  led_intensity_error_pct: 5\n");
  ASSERT_NE(as_built, drawing);
  const fs::path rig = dir.path() / "as-built.yaml";
  std::ofstream(rig) << as_built;
  const fs::path run = dir.path() / "run";
  const auto captured = Photorig("run " + SourceDir() + "/config/recipes/led-radiance.yaml --rig " + rig.string() +
                                     " --out " + run.string(),
                                 dir);
  ASSERT_EQ(captured.exit_code, 0) << captured.out << captured.err;

  const fs::path calibrated = dir.path() / "calibrated.yaml";
  const auto outcome = Photorig("calibrate radiance --json --run " + run.string() + " --albedo 0.8 --out-rig " +
                                    calibrated.string(),
                                dir);
  ASSERT_EQ(outcome.exit_code, 0) << outcome.out << outcome.err;
  const nlohmann::json fields = nlohmann::json::parse(outcome.out);
  EXPECT_EQ(fields["usable"], 48);
  EXPECT_EQ(fields["out_rig"], calibrated.string());

  const std::vector<double> truth = ReadColumn(run / "ground_truth/light_intensities.txt");
  const auto stated = photorig::config::LoadRigConfig(rig.string());
  const auto estimate = photorig::config::LoadRigConfig(calibrated.string());
  ASSERT_EQ(truth.size(), 48u);
  ASSERT_EQ(estimate.lights.leds.size(), truth.size());
  double stated_error = 0.0, calibrated_error = 0.0;
  for (std::size_t k = 0; k < truth.size(); ++k) {
    stated_error += std::pow(stated.lights.leds[k].intensity / truth[k] - 1.0, 2) / truth.size();
    calibrated_error += std::pow(estimate.lights.leds[k].intensity / truth[k] - 1.0, 2) / truth.size();
    // The LEDs are the simulator's Lambertian emitters.
    EXPECT_NEAR(estimate.lights.leds[k].cos_exponent, 1.0, 0.3) << k;
  }
  EXPECT_GT(std::sqrt(stated_error), 0.03);  // the error is there to be found
  EXPECT_LT(std::sqrt(calibrated_error), 0.01);
  // The copy states the LEDs as built: the simulator's error is gone, the record is there.
  const std::string written = ReadText(calibrated);
  EXPECT_EQ(written.find("led_intensity_error_pct"), std::string::npos);
  EXPECT_NE(written.find("radiance_calibration"), std::string::npos);
  EXPECT_TRUE(fs::exists(run / "results/led-radiance/report.json"));
  EXPECT_TRUE(fs::exists(run / "results/led-radiance/plane_mask.png"));

  // A calibrated rig is always a new file; a distant dome has no positions to calibrate against.
  const auto again = Photorig("calibrate radiance --run " + run.string() + " --albedo 0.8 --out-rig " +
                                  calibrated.string() + " --out " + (dir.path() / "again").string(),
                              dir);
  EXPECT_EQ(again.exit_code, 2);
  EXPECT_NE(again.err.find("exists"), std::string::npos) << again.err;
  const auto no_albedo = Photorig("calibrate radiance --run " + run.string() + " --albedo 1.5", dir);
  EXPECT_EQ(no_albedo.exit_code, 2);
  EXPECT_NE(no_albedo.err.find("albedo"), std::string::npos) << no_albedo.err;
}

}  // namespace
