// A near dome calibrated from its own captures, through the executable: the
// LED intensities and profiles from the led-radiance recipe's matte plane
// (`photorig calibrate radiance`), a calibration applied to frames taken
// before it (`photorig solve ps --rig`), and the whole chain from mirror balls
// and the plane to solved objects, against the simulator's LEDs as built.

#include "photorig/config/rig.h"
#include "test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

namespace {

namespace fs = std::filesystem;
using photorig::testing::AsBuiltRig;
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
  const fs::path rig = AsBuiltRig(dir.path(), "sim-dome-near.yaml", {"led_intensity_error_pct: 5"});
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

// The near dome as built, stated as drawn: LEDs 1.5 deg (6.5 mm) off their
// drawn positions and 5 % off their stated intensities.
fs::path AsBuiltNearDome(const TempDir& dir) {
  return AsBuiltRig(dir.path(), "sim-dome-near.yaml", {"led_direction_error_deg: 1.5", "led_intensity_error_pct: 5"});
}

double MeanErrorDeg(const fs::path& results) {
  return nlohmann::json::parse(ReadText(results / "report.json"))["ground_truth"]["mean_angular_error_deg"].get<double>();
}

TEST(SolveWithACalibratedRig, FramesTakenBeforeTheCalibrationAreSolvedWithIt) {
  TempDir dir;
  const fs::path rig = AsBuiltNearDome(dir), run = dir.path() / "run";
  const auto captured = Photorig("run " + SourceDir() + "/config/recipes/ps-sphere.yaml --no-solve --rig " +
                                     rig.string() + " --out " + run.string(),
                                 dir);
  ASSERT_EQ(captured.exit_code, 0) << captured.out << captured.err;
  const auto as_stated = Photorig("solve ps --method lambertian --run " + run.string() + " --out " +
                                      (dir.path() / "stated").string(),
                                  dir);
  ASSERT_EQ(as_stated.exit_code, 0) << as_stated.out << as_stated.err;

  // The LEDs as they were built, from the simulator's ground truth.
  YAML::Node truth = YAML::LoadFile(rig.string());
  truth["sim"].remove("led_direction_error_deg");
  truth["sim"].remove("led_intensity_error_pct");
  std::ifstream positions(run / "ground_truth/light_positions.txt");
  const std::vector<double> intensities = ReadColumn(run / "ground_truth/light_intensities.txt");
  YAML::Node leds = truth["lights"]["leds"];
  ASSERT_EQ(leds.size(), intensities.size());
  for (std::size_t k = 0; k < leds.size(); ++k) {
    double x = 0, y = 0, z = 0;
    ASSERT_TRUE(positions >> x >> y >> z);
    leds[k]["position_mm"] = std::vector<double>{x, y, z};
    leds[k]["intensity"] = intensities[k];
  }
  const fs::path truth_rig = dir.path() / "truth.yaml";
  std::ofstream(truth_rig) << truth;
  const auto calibrated = Photorig("solve ps --json --method lambertian --run " + run.string() + " --rig " +
                                       truth_rig.string() + " --out " + (dir.path() / "calibrated").string(),
                                   dir);
  ASSERT_EQ(calibrated.exit_code, 0) << calibrated.out << calibrated.err;
  const double stated_deg = MeanErrorDeg(dir.path() / "stated"), calibrated_deg = MeanErrorDeg(dir.path() / "calibrated");
  EXPECT_GT(stated_deg, 0.8);  // the dome as drawn is measurably off
  EXPECT_LT(calibrated_deg, 0.35) << "as stated: " << stated_deg << " deg";
  // The report says which rig the frames were solved with.
  EXPECT_NE(nlohmann::json::parse(calibrated.out)["provenance"].dump().find("truth.yaml"), std::string::npos);

  // A rig of another dome is refused naming it.
  const auto other = Photorig("solve ps --run " + run.string() + " --rig " + SourceDir() +
                                  "/config/rigs/sim-dome-96.yaml --out " + (dir.path() / "other").string(),
                              dir);
  EXPECT_EQ(other.exit_code, 2);
  EXPECT_NE(other.err.find("sim-dome-96.yaml"), std::string::npos) << other.err;
  EXPECT_NE(other.err.find("96 LEDs"), std::string::npos) << other.err;
}


// The acceptance of a near dome calibrated from its own captures only: LED
// positions from three mirror balls (led-positions recipe), intensities and
// profiles from a matte plane fitted at those positions (led-radiance recipe),
// and a sphere and the bumps captured on the dome as built, solved with the
// calibrated rig. Nothing of the truth reaches the solver but the frames.
TEST(NearDomeCalibratedFromCaptures, SolvesTheSphereAndTheBumpsWithinTheirBudgets) {
  TempDir dir;
  const fs::path rig = AsBuiltNearDome(dir);
  auto capture = [&](const std::string& recipe, const fs::path& out, const std::string& flags = "") {
    const auto outcome =
        Photorig("run " + SourceDir() + "/config/recipes/" + recipe + " --rig " + rig.string() + " --out " + out.string() + flags, dir);
    EXPECT_EQ(outcome.exit_code, 0) << recipe << ": " << outcome.out << outcome.err;
  };
  capture("led-positions.yaml", dir.path() / "balls");
  const fs::path positions = dir.path() / "balls/results/leds/rig.yaml";
  ASSERT_TRUE(fs::exists(positions));
  capture("led-radiance.yaml", dir.path() / "plane");
  const fs::path calibrated = dir.path() / "calibrated.yaml";
  const auto radiance = Photorig("calibrate radiance --run " + (dir.path() / "plane").string() + " --albedo 0.8 --rig " +
                                     positions.string() + " --out-rig " + calibrated.string(),
                                 dir);
  ASSERT_EQ(radiance.exit_code, 0) << radiance.out << radiance.err;

  for (const auto& [recipe, budget_deg] : {std::pair<std::string, double>{"ps-sphere.yaml", 1.0}, {"ps-bumps.yaml", 1.5}}) {
    const fs::path run = dir.path() / recipe;
    capture(recipe, run, " --no-solve");
    const auto drawn = Photorig("solve ps --method lambertian --run " + run.string() + " --out " + (run / "drawn").string(), dir);
    const auto solved = Photorig("solve ps --method lambertian --run " + run.string() + " --rig " + calibrated.string() +
                                     " --out " + (run / "calibrated").string(),
                                 dir);
    ASSERT_EQ(solved.exit_code, 0) << solved.out << solved.err;
    const double drawn_deg = MeanErrorDeg(run / "drawn"), calibrated_deg = MeanErrorDeg(run / "calibrated");
    EXPECT_LT(calibrated_deg, budget_deg) << recipe << ", the dome as drawn: " << drawn_deg << " deg";
    EXPECT_LT(calibrated_deg, drawn_deg) << recipe;
    std::printf("%s: as drawn %.3f deg, calibrated from captures %.3f deg\n", recipe.c_str(), drawn_deg, calibrated_deg);
  }
}

}  // namespace
