// From `photorig run config/recipes/brdf-gonio.yaml` on the simulated
// gonioreflectometer to `photorig solve brdf`: the chosen model is the one the
// simulated material was made from, its parameters within 5 % of the truth.
// And `photorig brdf fit|eval|convert` on measured tables of either format.

#include "../daemon/test_support.h"
#include "photorig/solvers/brdf/merl.h"
#include "photorig/solvers/brdf/models.h"
#include "photorig/solvers/brdf/pose_plan.h"
#include "photorig/solvers/brdf/rgl.h"
#include "photorig/solvers/brdf/samples.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <regex>

namespace {

using photorig::testing::ReadText;
using photorig::testing::RunPhotorig;
using photorig::testing::SourceDir;
using photorig::testing::TempDir;

// config/rigs/sim-gonio.yaml with the arms at 20x its simulated speed (the
// tests are about the measurement, not the moves) and `edit` applied.
std::string GonioRig(const TempDir& dir, const std::string& from = "", const std::string& to = "") {
  std::string text = std::regex_replace(ReadText(SourceDir() + "/config/rigs/sim-gonio.yaml"),
                                        std::regex("time_scale: [0-9.]+"), "time_scale: 200");
  if (!from.empty()) {
    const auto at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    text.replace(at, from.size(), to);
  }
  return dir.Write("rig.yaml", text);
}

// A recipe on the simulated material of config/recipes/brdf-gonio.yaml with these capture steps.
std::string GonioRecipe(const TempDir& dir, const std::string& name, const std::string& steps) {
  return dir.Write(name, "recipe: {name: " + name.substr(0, name.find('.')) +
                             "}\nsample:\n  name: s\n  sim_scene:\n    shape: sample_plane\n    radius_mm: 12\n"
                             "    albedo: {pattern: uniform, high: 0.4}\n"
                             "    brdf: {model: blinn_phong, rho_s: 0.15, exponent: 20}\n"
                             "capture:\n  exposure_us: 8000\n  steps:\n" + steps);
}

// Captures `recipe` on `rig` into DIR/<name> and solves it: the exit code, the log in DIR/<name>.log.
int RunAndSolve(const TempDir& dir, const std::string& recipe, const std::string& rig, const std::string& name,
                const std::string& solve_flags = "") {
  const std::string run = (dir.path() / name).string();
  EXPECT_EQ(RunPhotorig("run " + recipe + " --rig " + rig + " --out " + run, dir.path() / (name + "_run.log")), 0)
      << ReadText(dir.path() / (name + "_run.log"));
  return RunPhotorig("solve brdf --run " + run + " " + solve_flags, dir.path() / (name + ".log"));
}

nlohmann::json Report(const TempDir& dir, const std::string& name) {
  return nlohmann::json::parse(ReadText(dir.path() / name / "results" / "brdf" / "report.json"));
}

// The recipe's material: rho_d 0.4, the simulator's rho_s 0.15 at e = 20,
// which is k_s = 0.15 / c(20) = 0.50 in the fitted normalisation (docs/brdf.md).
const double kTrueKs = 0.15 / ((20.0 + 4.0) / (4.0 * (std::pow(2.0, -10.0) + 20.0)));

void ExpectTheMaterial(const nlohmann::json& report) {
  EXPECT_EQ(report["chosen"], "blinn_phong") << report.dump(2);
  const auto& fit = report["candidates"][1];
  ASSERT_EQ(fit["model"], "blinn_phong");
  EXPECT_NEAR(fit["diffuse"][0].get<double>(), 0.4, 0.05 * 0.4);
  EXPECT_NEAR(fit["specular"][0].get<double>(), kTrueKs, 0.05 * kTrueKs);
  EXPECT_NEAR(fit["shape"].get<double>(), 20.0, 0.05 * 20.0);
  EXPECT_TRUE(fit["lobe_identifiable"]);
}

TEST(BrdfEndToEnd, GonioRunFitsTheSimulatedMaterial) {
  TempDir dir;
  // The run completes under the rig's default health checks (a pose's longer
  // exposures may clip, only its shortest is judged) and ends with the fit:
  // the recipe's brdf solve stage.
  const std::string run = (dir.path() / "run").string();
  ASSERT_EQ(RunPhotorig("run " + SourceDir() + "/config/recipes/brdf-gonio.yaml --rig " + GonioRig(dir) + " --out " +
                            run + " --json",
                        dir.path() / "run.log"),
            0)
      << ReadText(dir.path() / "run.log");
  const std::string printed = ReadText(dir.path() / "run.log");
  EXPECT_NE(printed.find("\"chosen\": \"blinn_phong\""), std::string::npos) << printed;
  // Ceres' own logging (glog: "Logging before InitGoogleLogging", covariance
  // errors as "E1128 12:00:00.000 ... covariance_impl.cc") stays out of it:
  // the report says what a fit's covariance gave.
  EXPECT_EQ(printed.find("InitGoogleLogging"), std::string::npos) << printed;
  EXPECT_FALSE(std::regex_search(printed, std::regex("(^|\n)[IWEF][0-9]{4} [0-9:.]+ "))) << printed;
  const auto report = Report(dir, "run");
  // The recipe's plan: 9 x 6 configurations, 4 beyond the arms or the horizon.
  EXPECT_EQ(report["samples"], 50);
  EXPECT_EQ(report["bracketed_poses"], 50);
  // The peak clips at 32000 us; the bracket's shorter exposures measure it.
  EXPECT_TRUE(report["clipped_poses"].empty()) << report["clipped_poses"].dump();
  EXPECT_FALSE(report["peak_clipped"]);
  EXPECT_TRUE(report["peak_sampled"]);
  EXPECT_EQ(report["calibration"]["source"], "reference_target");
  // The target's frames fix the scale to well under a percent; the camera's
  // own response (1.5 e/us over 4 e/DN) is what it should find.
  EXPECT_LT(report["calibration"]["relative_sigma"].get<double>(), 0.01);
  EXPECT_NEAR(report["calibration"]["dn_per_radiance_per_us"].get<double>(), 0.375, 0.375 * 0.02);
  ExpectTheMaterial(report);

  // The stored samples say where each came from: its pose, and the longest
  // exposure the bracket merge used (32000 us unless the pose clipped there).
  std::vector<photorig::solvers::brdf::BrdfSample> samples;
  const auto read =
      photorig::solvers::brdf::ReadSamplesCsv((dir.path() / "run" / "results" / "brdf" / "samples.csv").string(), &samples);
  ASSERT_TRUE(read.IsSolutionUsable()) << read.message;
  ASSERT_EQ(samples.size(), 50u);
  // What clips is the signal, f_r cos theta_i: every pose whose longest exposure was left out is
  // brighter than every pose that kept it (give or take the block's spread).
  double dimmest_shortened = INFINITY, brightest_full = 0.0;
  for (const auto& sample : samples) {
    ASSERT_TRUE(sample.origin.has_value());
    const auto& o = *sample.origin;
    const auto dirs = photorig::solvers::brdf::ArmDirections({o.light_arm_deg, o.camera_arm_deg, o.sample_rotation_deg});
    EXPECT_LT((dirs.wi - sample.wi).norm(), 1e-9);
    EXPECT_LT((dirs.wo - sample.wo).norm(), 1e-9);
    EXPECT_TRUE(o.exposure_us == 2000 || o.exposure_us == 8000 || o.exposure_us == 32000) << o.exposure_us;
    EXPECT_EQ(o.frames % 2, 0);  // two repeats per exposure used
    const double signal = sample.value.maxCoeff() * sample.wi.z();
    if (o.exposure_us < 32000) {
      dimmest_shortened = std::min(dimmest_shortened, signal);
    } else {
      brightest_full = std::max(brightest_full, signal);
    }
  }
  ASSERT_TRUE(std::isfinite(dimmest_shortened));  // the peak, at least, clips at 32000 us
  EXPECT_GT(dimmest_shortened, 0.9 * brightest_full);
}

// A measured material through the instrument: Ngan et al. 2005's
// Cook-Torrance fit of MERL blue-metallic-paint, tabulated as a MERL file by
// `brdf convert`, is the rig's simulated sample under the shipped recipe. The grey
// camera sees the mean of the table's channels; the fit must find the model
// and its lobe from what the arms and the camera measured.
TEST(BrdfEndToEnd, TheInstrumentMeasuresAMeasuredMaterial) {
  TempDir dir;
  const std::string model = dir.Write("blue.json", R"({"model": "cook_torrance", "diffuse": [0.0135, 0.00848, 0.0244],
      "specular": [0.0719, 0.0589, 0.0813], "shape": 0.231, "fresnel_f0": 0.638})");
  const std::string table = (dir.path() / "blue-metallic-paint.binary").string();
  ASSERT_EQ(RunPhotorig("brdf convert " + model + " " + table, dir.path() / "convert.log"), 0)
      << ReadText(dir.path() / "convert.log");
  const std::string rig = GonioRig(dir, "brdf: {model: blinn_phong, rho_s: 0.15, exponent: 20}",
                                    "brdf: {model: tabulated, table: " + table + "}");
  ASSERT_EQ(RunAndSolve(dir, SourceDir() + "/config/recipes/brdf-gonio.yaml", rig, "measured"), 0)
      << ReadText(dir.path() / "measured.log");
  const auto report = Report(dir, "measured");
  EXPECT_TRUE(report["clipped_poses"].empty()) << report["clipped_poses"].dump();
  ASSERT_EQ(report["chosen"], "cook_torrance") << report.dump(2);
  const auto& fit = *std::find_if(report["candidates"].begin(), report["candidates"].end(),
                                  [](const nlohmann::json& c) { return c["model"] == "cook_torrance"; });
  const double diffuse = (0.0135 + 0.00848 + 0.0244) / 3, specular = (0.0719 + 0.0589 + 0.0813) / 3;
  EXPECT_NEAR(fit["diffuse"][0].get<double>(), diffuse, 0.05 * diffuse);
  EXPECT_NEAR(fit["specular"][0].get<double>(), specular, 0.05 * specular);
  EXPECT_NEAR(fit["shape"].get<double>(), 0.231, 0.05 * 0.231);
  EXPECT_NEAR(fit["fresnel_f0"].get<double>(), 0.638, 0.05 * 0.638);
}

const nlohmann::json& Candidate(const nlohmann::json& report, const std::string& model) {
  return *std::find_if(report["candidates"].begin(), report["candidates"].end(),
                       [&](const nlohmann::json& c) { return c["model"] == model; });
}

// A colour camera: config/rigs/sim-gonio-colour.yaml (an RGGB mosaic with the
// Nikon D5100's sensitivities under D65) measures its blue-metallic-paint
// sample, given per channel, under the shipped recipe. Each channel has its
// own K from the grey target (the sensitivities differ), and the fit gives
// each channel's diffuse and specular back. The rig's colour model is
// root-polynomial, so it is reported and not applied; a linear one, put in
// the manifest's place, converts the samples, and the fitted weights follow it.
TEST(BrdfEndToEnd, AColourCameraGivesOneCalibratedValuePerChannel) {
  TempDir dir;
  std::string rig_text = std::regex_replace(ReadText(SourceDir() + "/config/rigs/sim-gonio-colour.yaml"),
                                            std::regex("time_scale: [0-9.]+"), "time_scale: 200");
  rig_text = std::regex_replace(rig_text, std::regex("\\.\\./color/"),
                                std::filesystem::absolute(SourceDir() + "/config/color/").string());
  ASSERT_EQ(RunAndSolve(dir, SourceDir() + "/config/recipes/brdf-gonio.yaml", dir.Write("colour.yaml", rig_text),
                        "colour"),
            0)
      << ReadText(dir.path() / "colour.log");
  const auto report = Report(dir, "colour");
  EXPECT_EQ(report["mosaic"], "RGGB");
  EXPECT_EQ(report["channels"], "camera");
  EXPECT_EQ(report["samples"], 50);
  EXPECT_TRUE(report["clipped_poses"].empty()) << report["clipped_poses"].dump();
  const auto& k = report["calibration"]["channel_dn_per_radiance_per_us"];
  EXPECT_EQ(report["calibration"]["channel_sites"], nlohmann::json({16, 32, 16}));
  // Green is the simulated camera's unit (a white gives 1 in green): the sensor's 0.375.
  EXPECT_NEAR(k[1].get<double>(), 0.375, 0.02 * 0.375);
  EXPECT_LT(k[0].get<double>(), 0.8 * k[1].get<double>()) << k;
  EXPECT_LT(k[2].get<double>(), 0.95 * k[1].get<double>()) << k;
  EXPECT_GT(std::abs(k[0].get<double>() - k[2].get<double>()), 0.1 * k[1].get<double>()) << k;
  ASSERT_EQ(report["chosen"], "cook_torrance") << report.dump(2);
  const auto& fit = Candidate(report, "cook_torrance");
  const double diffuse[3] = {0.0135, 0.00848, 0.0244}, specular[3] = {0.0719, 0.0589, 0.0813};
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(fit["diffuse"][c].get<double>(), diffuse[c], 0.03 * diffuse[c]) << c;
    EXPECT_NEAR(fit["specular"][c].get<double>(), specular[c], 0.03 * specular[c]) << c;
  }
  EXPECT_NEAR(fit["shape"].get<double>(), 0.231, 0.03 * 0.231);
  EXPECT_NEAR(fit["fresnel_f0"].get<double>(), 0.638, 0.05 * 0.638);
  EXPECT_EQ(report["color_model"]["model"], "root-poly-2");
  EXPECT_FALSE(report["color_model"]["applied"]);
  EXPECT_NE(report["color_model"]["note"].get<std::string>().find("not a 3 x 3 matrix"), std::string::npos);
  const std::string log = ReadText(dir.path() / "colour.log");
  EXPECT_NE(log.find("K per channel R "), std::string::npos) << log;
  EXPECT_NE(log.find("not applied"), std::string::npos) << log;

  // A linear model that reads camera RGB as linear sRGB: the conversion is
  // then diag(K) / Y(K), which undoes the target's white balance, and the
  // fit's per-channel weights are the camera fit's times it.
  const std::string linear = dir.Write("linear.yaml", R"(format: photorig-color-model/1
model: linear
loss: xyz
illuminant: D65
input_scale: 1
coefficients:
  - [0.4123908, 0.2126390, 0.0193308]
  - [0.3575843, 0.7151687, 0.1191948]
  - [0.1804808, 0.0721923, 0.9505322]
white_xyz: [0.9504559, 1.0, 1.0890578]
)");
  const auto manifest_path = dir.path() / "colour" / "manifest.json";
  auto manifest = nlohmann::json::parse(ReadText(manifest_path));
  manifest["camera"]["color_model"]["path"] = linear;
  dir.Write("colour/manifest.json", manifest.dump());
  ASSERT_EQ(RunPhotorig("solve brdf --run " + (dir.path() / "colour").string(), dir.path() / "linear.log"), 0)
      << ReadText(dir.path() / "linear.log");
  const auto srgb = Report(dir, "colour");
  EXPECT_EQ(srgb["channels"], "linear_srgb");
  ASSERT_TRUE(srgb["color_model"]["applied"]) << srgb["color_model"].dump();
  const double y = 0.2126 * k[0].get<double>() + 0.7152 * k[1].get<double>() + 0.0722 * k[2].get<double>();
  const auto& matrix = srgb["color_model"]["camera_to_linear_srgb"];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(matrix[r][c].get<double>(), r == c ? k[c].get<double>() / y : 0.0, 2e-3) << r << " " << c;
  ASSERT_EQ(srgb["chosen"], "cook_torrance");
  const auto& converted = Candidate(srgb, "cook_torrance");
  for (int c = 0; c < 3; ++c) {
    double d = 0.0, s = 0.0;
    for (int j = 0; j < 3; ++j) {
      d += matrix[c][j].get<double>() * fit["diffuse"][j].get<double>();
      s += matrix[c][j].get<double>() * fit["specular"][j].get<double>();
    }
    EXPECT_NEAR(converted["diffuse"][c].get<double>(), d, 0.01 * d) << c;
    EXPECT_NEAR(converted["specular"][c].get<double>(), s, 0.01 * s) << c;
  }
  EXPECT_NEAR(converted["shape"].get<double>(), fit["shape"].get<double>(), 1e-3 * fit["shape"].get<double>());
}

// Without a bracket the peak poses clip at the long exposure: each is
// dropped, counted and listed, and the report says the peak was clipped.
TEST(BrdfEndToEnd, WithoutABracketTheClippedPeakIsFlagged) {
  TempDir dir;
  // The run's health checks would stop at the first overexposed frame; here the solve is on trial.
  const std::string rig = GonioRig(dir, "sim:\n  seed", "health: {max_clipped_fraction: 1}\nsim:\n  seed");
  const std::string recipe = GonioRecipe(dir, "single.yaml",
                                         "    - dark: {count: 2, exposures_us: [8000, 32000]}\n"
                                         "    - reference_target: {count: 2, exposures_us: [8000]}\n"
                                         "    - poses:\n        exposures_us: [32000]\n        grid:\n"
                                         "          light_arm_deg: [-40, -25]\n"
                                         "          camera_arm_deg: [5, 15, 25, 35, 45, 55, 65, 75]\n");
  RunAndSolve(dir, recipe, rig, "single");
  const auto report = Report(dir, "single");
  EXPECT_TRUE(report["peak_clipped"]) << report.dump(2);
  ASSERT_GE(report["clipped_poses"].size(), 1u);
  EXPECT_EQ(report["samples"].get<int>() + static_cast<int>(report["clipped_poses"].size()), 16);
  EXPECT_NE(report.value("warning", "").find("specular peak was clipped"), std::string::npos);
  EXPECT_NE(ReadText(dir.path() / "single.log").find("warning: the specular peak was clipped"), std::string::npos);
}

// Repeats scatter as the sensor's noise model says: the pooled ratio of
// their spread to the propagated deviation is 1 within 4 of its own sampling
// deviations, sqrt(1 / (2 dof)).
TEST(BrdfEndToEnd, PropagatedDeviationsMatchTheRepeatsSpread) {
  TempDir dir;
  const std::string recipe = GonioRecipe(dir, "repeats.yaml",
                                         "    - dark: {count: 6, exposures_us: [2000, 8000]}\n"
                                         "    - reference_target: {count: 2, exposures_us: [8000]}\n"
                                         "    - poses:\n        exposures_us: [2000, 8000]\n        count: 8\n"
                                         "        grid: {light_arm_deg: [-55, -25], camera_arm_deg: [5, 25, 45, 65]}\n");
  ASSERT_EQ(RunAndSolve(dir, recipe, GonioRig(dir), "repeats"), 0) << ReadText(dir.path() / "repeats.log");
  const auto noise = Report(dir, "repeats")["noise"];
  const int dof = noise["repeat_dof"];
  EXPECT_EQ(dof, 8 * 2 * 7);
  EXPECT_NEAR(noise["repeat_sigma_ratio"].get<double>(), 1.0, 4.0 * std::sqrt(1.0 / (2.0 * dof))) << noise.dump();
  EXPECT_EQ(noise["shot_from"], "camera e_per_dn");
  // The read noise measured from the darks: the simulated 6 e at 4 e/DN, plus quantisation.
  EXPECT_NEAR(noise["read_sigma_dn"].get<double>(), std::sqrt(1.5 * 1.5 + 1.0 / 12.0), 0.1);

  // A camera that states no conversion gain: the shot term comes from the
  // repeats' spread, 1 / (4 e/DN) here.
  const auto manifest_path = dir.path() / "repeats" / "manifest.json";
  auto manifest = nlohmann::json::parse(ReadText(manifest_path));
  manifest["camera"]["e_per_dn"] = 0.0;
  dir.Write("repeats/manifest.json", manifest.dump());
  ASSERT_EQ(RunPhotorig("solve brdf --run " + (dir.path() / "repeats").string(), dir.path() / "estimated.log"), 0)
      << ReadText(dir.path() / "estimated.log");
  const auto estimated = Report(dir, "repeats")["noise"];
  EXPECT_EQ(estimated["shot_from"], "repeats");
  EXPECT_NEAR(estimated["shot_dn_per_dn"].get<double>(), 0.25, 0.25 * 0.1) << estimated.dump();
}

// The reference target sets the scale, not the camera's stated response:
// a camera that states a wrong one still gives the material; trusting it
// instead (--calibration camera) is off by the stated error. A run without
// target frames is refused unless the camera's response is asked for.
TEST(BrdfEndToEnd, TheReferenceTargetSetsTheScale) {
  TempDir dir;
  const std::string wrong = GonioRig(dir, "  exposure_us: 4000\n", "  exposure_us: 4000\n  dn_per_radiance_per_us: 0.75\n");
  const std::string steps = "    - poses:\n        exposures_us: [2000, 8000, 32000]\n        grid:\n"
                            "          light_arm_deg: [-55, -40, -25, -10]\n"
                            "          camera_arm_deg: [5, 15, 25, 35, 45, 55, 65]\n";
  const std::string darks = "    - dark: {count: 2, exposures_us: [2000, 8000, 32000]}\n";
  const std::string recipe = GonioRecipe(
      dir, "wrong.yaml", darks + "    - reference_target: {count: 2, exposures_us: [2000, 8000]}\n" + steps);
  ASSERT_EQ(RunAndSolve(dir, recipe, wrong, "wrong"), 0) << ReadText(dir.path() / "wrong.log");
  ExpectTheMaterial(Report(dir, "wrong"));
  EXPECT_NEAR(Report(dir, "wrong")["calibration"]["camera_dn_per_radiance_per_us"].get<double>(), 0.75, 1e-12);
  ASSERT_EQ(RunPhotorig("solve brdf --calibration camera --run " + (dir.path() / "wrong").string(),
                        dir.path() / "camera.log"),
            0)
      << ReadText(dir.path() / "camera.log");
  const auto trusted = Report(dir, "wrong");
  EXPECT_EQ(trusted["calibration"]["source"], "camera_response");
  EXPECT_NEAR(trusted["candidates"][1]["diffuse"][0].get<double>(), 0.4 * 0.375 / 0.75, 0.05 * 0.2);

  const std::string no_target = GonioRecipe(dir, "none.yaml", darks + steps);
  EXPECT_EQ(RunAndSolve(dir, no_target, GonioRig(dir), "none"), 2);
  EXPECT_NE(ReadText(dir.path() / "none.log").find("no reference_target frames"), std::string::npos)
      << ReadText(dir.path() / "none.log");
  EXPECT_EQ(RunPhotorig("solve brdf --calibration camera --run " + (dir.path() / "none").string(),
                        dir.path() / "none_camera.log"),
            0)
      << ReadText(dir.path() / "none_camera.log");
}

// A saturated or too dark target is refused (exit 1), never used.
TEST(BrdfEndToEnd, ASaturatedOrDarkReferenceTargetIsRefused) {
  TempDir dir;
  // The run's health checks would stop at an overexposed or unlit frame; here the solve is on trial.
  const std::string rig = GonioRig(dir, "sim:\n  seed", "health: {enabled: false}\nsim:\n  seed");
  const std::string poses = "    - poses: {exposures_us: [8000], list: [{light_arm_deg: -40, camera_arm_deg: 20}]}\n";
  struct Case {
    const char* name;
    const char* target_exposures;
    const char* fragment;
  };
  // The target gives 0.118 DN per us: 7550 DN at 64000 us (full well at
  // 3750), 2.4 DN at 20 us under 1.5 DN of read noise.
  for (const Case& c : {Case{"bright", "64000", "saturated even at its shortest exposure (64000 us)"},
                        Case{"dark", "20", "the reference target is too dark"}}) {
    const std::string recipe = GonioRecipe(
        dir, std::string(c.name) + ".yaml",
        "    - dark: {count: 2, exposures_us: [8000, " + std::string(c.target_exposures) + "]}\n"
        "    - reference_target: {count: 2, exposures_us: [" + c.target_exposures + "]}\n" + poses);
    EXPECT_EQ(RunAndSolve(dir, recipe, rig, c.name), 1) << c.name;
    EXPECT_NE(ReadText(dir.path() / (std::string(c.name) + ".log")).find(c.fragment), std::string::npos)
        << ReadText(dir.path() / (std::string(c.name) + ".log"));
    EXPECT_FALSE(std::filesystem::exists(dir.path() / c.name / "results" / "brdf" / "report.json"));
  }
  // Darks at another exposure than the poses': the offsets there are not known (exit 2).
  const std::string recipe = GonioRecipe(dir, "undark.yaml",
                                         "    - dark: {count: 2, exposures_us: [2000]}\n"
                                         "    - reference_target: {count: 2, exposures_us: [2000]}\n" + poses);
  EXPECT_EQ(RunAndSolve(dir, recipe, rig, "undark"), 2);
  EXPECT_NE(ReadText(dir.path() / "undark.log").find("no dark frame at exposure 8000 us"), std::string::npos)
      << ReadText(dir.path() / "undark.log");
}

// A GGX written as an RGL .bsdf by the library, converted to MERL by the
// command, and each file fitted by `photorig brdf fit`: both formats go the
// same way to the model selection and give back the model and its parameters.
TEST(BrdfEndToEnd, MeasuredTablesOfEitherFormatFitTheModelTheyWereMadeFrom) {
  namespace brdf = photorig::solvers::brdf;
  TempDir dir;
  brdf::ModelParams ggx;
  ggx.model = brdf::Model::kGgx;
  ggx.diffuse = {0.2, 0.15, 0.1};
  ggx.specular = {0.9, 0.8, 0.6};
  ggx.shape = 0.25;
  // Finer than the default tabulation: fitted to the default one (1.2 % RMS
  // interpolation error) rho_d comes out 7-11 % high; at this one every
  // parameter lies within 3.6 % (docs/brdf.md).
  brdf::RglTabulation tab;
  tab.theta_i_count = 32;
  tab.sample_resolution = 64;
  tab.ndf_resolution = 128;
  tab.ndf_roughness = 0.25;
  brdf::TensorFile file;
  ASSERT_TRUE(brdf::TabulateRgl([&](const brdf::DirectionPair& d) { return brdf::Evaluate(ggx, d.wi, d.wo); }, tab,
                                &file)
                  .IsSolutionUsable());
  const std::string rgl = (dir.path() / "ggx.bsdf").string(), merl = (dir.path() / "ggx.binary").string();
  ASSERT_TRUE(brdf::WriteTensorFile(rgl, file).IsSolutionUsable());
  ASSERT_EQ(RunPhotorig("brdf convert " + rgl + " " + merl, dir.path() / "convert.log"), 0)
      << ReadText(dir.path() / "convert.log");
  for (const std::string& table : {rgl, merl}) {
    const auto out = dir.path() / ("fit_" + std::filesystem::path(table).extension().string().substr(1));
    ASSERT_EQ(RunPhotorig("brdf fit " + table + " --out " + out.string(), dir.path() / "fit.log"), 0)
        << ReadText(dir.path() / "fit.log");
    const auto report = nlohmann::json::parse(ReadText(out / "report.json"));
    EXPECT_EQ(report["loss"], "log");
    EXPECT_EQ(report["chosen"], "ggx") << report.dump(2);
    const auto ggx_fit = std::find_if(report["candidates"].begin(), report["candidates"].end(),
                                      [](const nlohmann::json& c) { return c["model"] == "ggx"; });
    ASSERT_NE(ggx_fit, report["candidates"].end());
    const auto& fit = *ggx_fit;
    // GGX's lobe scale and F0 part only by the Fresnel rise toward grazing,
    // where the tables resolve least: the lobe's height at normal incidence,
    // scale x F0, is what both formats must give back, and the scale near 1.
    const double scale = fit.value("specular_scale", 1.0);
    EXPECT_NEAR(scale, 1.0, 0.1) << table;
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(fit["diffuse"][c].get<double>(), ggx.diffuse[c], 0.05 * ggx.diffuse[c]) << table << " " << c;
      EXPECT_NEAR(scale * fit["specular"][c].get<double>(), ggx.specular[c], 0.05 * ggx.specular[c])
          << table << " " << c;
    }
    EXPECT_NEAR(fit["shape"].get<double>(), ggx.shape, 0.05 * ggx.shape) << table;
  }
  // One configuration, and one below the horizon, which has no value.
  EXPECT_EQ(RunPhotorig("brdf eval " + rgl + " --wi 30 0 --wo 40 180", dir.path() / "eval.log"), 0)
      << ReadText(dir.path() / "eval.log");
  EXPECT_NE(ReadText(dir.path() / "eval.log").find("f_r = "), std::string::npos);
  EXPECT_EQ(RunPhotorig("brdf eval " + merl + " --wi 30 0 --wo 95 0", dir.path() / "eval.log"), 1);
  // A damaged file is a usage error naming the file and the fault.
  const std::string bad = dir.Write("bad.bsdf", "not a tensor file at all");
  EXPECT_EQ(RunPhotorig("brdf fit " + bad, dir.path() / "bad.log"), 2);
  const std::string log = ReadText(dir.path() / "bad.log");
  EXPECT_NE(log.find(bad), std::string::npos) << log;
  EXPECT_NE(log.find("wrong header"), std::string::npos) << log;
}

TEST(BrdfEndToEnd, PlannedPosesPassTheRigsDryRun) {
  TempDir dir;
  const std::string rig = std::filesystem::absolute(SourceDir() + "/config/rigs/sim-gonio.yaml").string();
  // theta_d >= 10 deg keeps the arms 20 deg apart; theta_h + theta_d <= 70 deg keeps them within +-85.
  ASSERT_EQ(RunPhotorig("plan brdf --rig " + rig + " --theta-h 0 30 4 --theta-d 10 40 4", dir.path() / "plan.log"), 0)
      << ReadText(dir.path() / "plan.log");
  const std::string plan = ReadText(dir.path() / "plan.log");
  EXPECT_NE(plan.find("# 16 poses"), std::string::npos) << plan;
  EXPECT_NE(plan.find("# 0 refused, 0 grazing"), std::string::npos) << plan;
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
  // The plan step the command names makes the same 16 poses when the recipe loads.
  const std::string marker = "# in a recipe, the same plan: ";
  const std::size_t at = plan.find(marker);
  ASSERT_NE(at, std::string::npos) << plan;
  const std::string plan_step = plan.substr(at + marker.size(), plan.find('\n', at) - at - marker.size());
  const std::string planned_recipe =
      dir.Write("plan_step.yaml", "recipe:\n  name: planned\n  rig: " + rig +
                                      "\ncapture:\n  exposure_us: 4000\n  steps:\n    " + plan_step + "\n");
  ASSERT_EQ(RunPhotorig("dry-run " + planned_recipe + " --steps", dir.path() / "dry_plan.log"), 0)
      << ReadText(dir.path() / "dry_plan.log");
  EXPECT_NE(ReadText(dir.path() / "dry_plan.log").find("16 frames"), std::string::npos)
      << ReadText(dir.path() / "dry_plan.log");

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

// A fitted model tabulated for renderers: a model's JSON to a MERL table (its
// values at the cell centres), that table fitted back to the same model, and
// the fit's report.json tabulated in turn.
TEST(BrdfEndToEnd, AFittedModelConvertsToATableForRenderers) {
  namespace brdf = photorig::solvers::brdf;
  TempDir dir;
  brdf::ModelParams truth;
  truth.model = brdf::Model::kTwoBlinnPhong;
  truth.diffuse = {0.2, 0.12, 0.05};
  truth.specular = {0.08, 0.08, 0.08};
  truth.shape = 400.0;
  truth.specular2 = {0.3, 0.2, 0.1};
  truth.shape2 = 12.0;
  const std::string spec = dir.Write("model.json",
                                     R"({"model": "two_blinn_phong", "diffuse": [0.2, 0.12, 0.05],
                                         "specular": [0.08, 0.08, 0.08], "shape": 400,
                                         "specular2": [0.3, 0.2, 0.1], "shape2": 12})");
  const std::string table = (dir.path() / "model.binary").string();
  ASSERT_EQ(RunPhotorig("brdf convert " + spec + " " + table, dir.path() / "convert.log"), 0)
      << ReadText(dir.path() / "convert.log");
  brdf::MerlTable read;
  ASSERT_TRUE(brdf::ReadMerl(table, &read).IsSolutionUsable());
  std::mt19937 rng(2);
  std::uniform_int_distribution<int> h(0, 89), d(0, 89), p(0, 179);
  for (int k = 0; k < 500; ++k) {
    const int ih = h(rng), id = d(rng), ip = p(rng);
    const brdf::DirectionPair dirs = brdf::FromHalfDiff(brdf::MerlTable::CellCentre(ih, id, ip));
    const auto cell = read.EvaluateCell(brdf::MerlTable::CellIndex(ih, id, ip));
    ASSERT_EQ(cell.has_value(), dirs.wi.z() > 0.0 && dirs.wo.z() > 0.0);
    if (cell) {
      const Eigen::Vector3d truth_value = brdf::Evaluate(truth, dirs.wi, dirs.wo);
      EXPECT_LT(((*cell - truth_value).array().abs() / truth_value.array()).maxCoeff(), 1e-12);
    }
  }
  // Fitted back: two lobes chosen, every parameter within 2 %.
  const auto out = dir.path() / "fit";
  ASSERT_EQ(RunPhotorig("brdf fit " + table + " --out " + out.string(), dir.path() / "fit.log"), 0)
      << ReadText(dir.path() / "fit.log");
  const auto report = nlohmann::json::parse(ReadText(out / "report.json"));
  ASSERT_EQ(report["chosen"], "two_blinn_phong") << report.dump(2);
  EXPECT_NE(report["reason"].get<std::string>().find("held-out"), std::string::npos) << report["reason"];
  const auto fit = *std::find_if(report["candidates"].begin(), report["candidates"].end(),
                                 [](const nlohmann::json& c) { return c["model"] == "two_blinn_phong"; });
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(fit["diffuse"][c].get<double>(), truth.diffuse[c], 0.02 * truth.diffuse[c]);
    EXPECT_NEAR(fit["specular"][c].get<double>(), truth.specular[c], 0.02 * truth.specular[c]);
    EXPECT_NEAR(fit["specular2"][c].get<double>(), truth.specular2[c], 0.02 * truth.specular2[c]);
  }
  EXPECT_NEAR(fit["shape"].get<double>(), truth.shape, 0.02 * truth.shape);
  EXPECT_NEAR(fit["shape2"].get<double>(), truth.shape2, 0.02 * truth.shape2);
  // Training and held-out errors of every model: the one-lobe fits' far above the two lobes'.
  for (const nlohmann::json& c : report["candidates"]) {
    if (c["model"] == "two_blinn_phong") continue;
    EXPECT_GT(c["train_rms"].get<double>(), 10.0 * fit["train_rms"].get<double>()) << c["model"];
    EXPECT_GT(c["held_out_rms"].get<double>(), 10.0 * fit["held_out_rms"].get<double>()) << c["model"];
  }
  // The report tabulated: its chosen model, or a candidate named, to either format.
  const std::string again = (dir.path() / "again.binary").string();
  ASSERT_EQ(RunPhotorig("brdf convert " + (out / "report.json").string() + " " + again, dir.path() / "again.log"), 0)
      << ReadText(dir.path() / "again.log");
  brdf::MerlTable refitted;
  ASSERT_TRUE(brdf::ReadMerl(again, &refitted).IsSolutionUsable());
  const brdf::DirectionPair probe = brdf::FromHalfDiff(brdf::MerlTable::CellCentre(3, 20, 40));
  EXPECT_NEAR((*refitted.Evaluate(probe.wi, probe.wo))[0], (*read.Evaluate(probe.wi, probe.wo))[0],
              0.02 * (*read.Evaluate(probe.wi, probe.wo))[0]);
  EXPECT_EQ(RunPhotorig("brdf convert " + (out / "report.json").string() + " --model ggx " +
                            (dir.path() / "ggx.bsdf").string(),
                        dir.path() / "ggx.log"),
            0)
      << ReadText(dir.path() / "ggx.log");
  EXPECT_TRUE(std::filesystem::exists(dir.path() / "ggx.bsdf"));
  // Refused, naming the file and the fault: a candidate the report lacks, an unknown model.
  EXPECT_EQ(RunPhotorig("brdf convert " + (out / "report.json").string() + " --model nope " + again,
                        dir.path() / "nope.log"),
            2);
  EXPECT_NE(ReadText(dir.path() / "nope.log").find("no 'nope' fit"), std::string::npos)
      << ReadText(dir.path() / "nope.log");
  // A model whose values overflow the table: refused (exit 1) naming where, and nothing written.
  const std::string huge = dir.Write("huge.json", R"({"model": "lambertian", "diffuse": [1e308, 1e308, 1e308]})");
  for (const char* extension : {".binary", ".bsdf"}) {
    const std::string table = (dir.path() / (std::string("huge") + extension)).string();
    EXPECT_EQ(RunPhotorig("brdf convert " + huge + " " + table, dir.path() / "huge.log"), 1) << extension;
    const std::string refused = ReadText(dir.path() / "huge.log");
    EXPECT_NE(refused.find(" is infinite"), std::string::npos) << refused;
    EXPECT_NE(refused.find(extension == std::string(".binary") ? "theta_h bin" : "theta_i"), std::string::npos)
        << refused;
    EXPECT_FALSE(std::filesystem::exists(table)) << table;
  }
  const std::string bad = dir.Write("bad.json", R"({"model": "phong", "diffuse": [0.1, 0.1, 0.1]})");
  EXPECT_EQ(RunPhotorig("brdf convert " + bad + " " + again, dir.path() / "bad.log"), 2);
  const std::string log = ReadText(dir.path() / "bad.log");
  EXPECT_NE(log.find(bad), std::string::npos) << log;
  EXPECT_NE(log.find("unknown model 'phong'"), std::string::npos) << log;
}

// config/recipes/brdf-gonio-adaptive.yaml: a near-mirror lobe (Blinn-Phong
// e = 5000, about 1 deg wide) that a uniform plan steps over. Dry-run states
// the most the passes add; the run adds two passes of 12 poses on the lobe's
// flanks and the fit of all 51 poses recovers the material (the coarse poses
// alone do not: tests/daemon/test_gonio.cpp).
TEST(BrdfEndToEnd, AnAdaptivePlanMeasuresANarrowLobe) {
  TempDir dir;
  const std::string adaptive = SourceDir() + "/config/recipes/brdf-gonio-adaptive.yaml";
  ASSERT_EQ(RunPhotorig("dry-run " + adaptive + " --rig " + GonioRig(dir), dir.path() / "dry.log"), 0)
      << ReadText(dir.path() / "dry.log");
  EXPECT_NE(ReadText(dir.path() / "dry.log").find("a coarse pass of 27 poses, then up to 2 x 12 poses added after the "
                                                  "coarse pass (at most 144 frames"),
            std::string::npos)
      << ReadText(dir.path() / "dry.log");

  ASSERT_EQ(RunAndSolve(dir, adaptive, GonioRig(dir), "adaptive"), 0) << ReadText(dir.path() / "adaptive.log");
  const std::string run_log = ReadText(dir.path() / "adaptive_run.log");
  EXPECT_NE(run_log.find("adaptive pass 1: 12 poses added (72 frames) from 27 samples"), std::string::npos) << run_log;
  EXPECT_NE(run_log.find("adaptive pass 2: 12 poses added (72 frames) from 39 samples"), std::string::npos) << run_log;
  const auto passes = nlohmann::json::parse(ReadText(dir.path() / "adaptive" / "adaptive_passes.json"));
  ASSERT_EQ(passes.size(), 2u) << passes.dump();
  EXPECT_EQ(passes[1]["poses_added"], 12);
  const auto report = Report(dir, "adaptive");
  EXPECT_EQ(report["samples"], 27 + 24);
  EXPECT_TRUE(report["clipped_poses"].empty()) << report["clipped_poses"].dump();
  ASSERT_EQ(report["chosen"], "blinn_phong") << report.dump(2);
  const auto& fit = report["candidates"][1];
  const double e = 5000.0, ks = 0.15 * 4.0 * e / (e + 4.0);
  EXPECT_NEAR(fit["diffuse"][0].get<double>(), 0.4, 0.05 * 0.4);
  EXPECT_NEAR(fit["specular"][0].get<double>(), ks, 0.05 * ks);
  EXPECT_NEAR(fit["shape"].get<double>(), e, 0.05 * e);

}


// `photorig brdf fit` chooses the simplest family that made a table: a
// one-lobe Blinn-Phong, not two lobes (whose held-out gain is within the
// fits' precision), and GGX for a GGX lobe without a Fresnel rise (F0 = 1,
// its height the scale s), not Ward, with its parameters back.
TEST(BrdfEndToEnd, BrdfFitChoosesTheFamilyThatMadeTheTable) {
  TempDir dir;
  struct Case {
    const char* name;
    const char* spec;
  };
  for (const Case& c : {Case{"blinn_phong", R"({"model": "blinn_phong", "diffuse": [0.25, 0.15, 0.05],
                                               "specular": [0.4, 0.3, 0.2], "shape": 60})"},
                        Case{"ggx", R"({"model": "ggx", "diffuse": [0.3, 0.2, 0.1], "specular": [1, 1, 1],
                                       "shape": 0.2, "specular_scale": 0.3})"}}) {
    SCOPED_TRACE(c.name);
    const std::string spec = dir.Write(std::string(c.name) + ".json", c.spec);
    const std::string table = (dir.path() / (std::string(c.name) + ".binary")).string();
    ASSERT_EQ(RunPhotorig("brdf convert " + spec + " " + table, dir.path() / "convert.log"), 0)
        << ReadText(dir.path() / "convert.log");
    const auto out = dir.path() / (std::string(c.name) + "_fit");
    ASSERT_EQ(RunPhotorig("brdf fit " + table + " --out " + out.string(), dir.path() / "fit.log"), 0)
        << ReadText(dir.path() / "fit.log");
    const auto report = nlohmann::json::parse(ReadText(out / "report.json"));
    EXPECT_EQ(report["chosen"], c.name) << report["reason"];
    const auto fit = *std::find_if(report["candidates"].begin(), report["candidates"].end(),
                                   [&](const nlohmann::json& f) { return f["model"] == c.name; });
    EXPECT_EQ(fit["termination"], "success");
    const auto truth = nlohmann::json::parse(c.spec);
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(fit["diffuse"][k].get<double>(), truth["diffuse"][k].get<double>(),
                  0.01 * truth["diffuse"][k].get<double>());
    if (truth.contains("specular_scale")) {
      EXPECT_NEAR(fit["specular_scale"].get<double>(), 0.3, 0.003);
    }
  }
}

// `photorig brdf fit` on a table reports every candidate's error over all
// cells beside the sample estimate, and with --keep-table makes the table
// itself the material, byte for byte.
TEST(BrdfEndToEnd, BrdfFitReportsTheAllCellErrorAndKeepsTheTable) {
  TempDir dir;
  const std::string spec = dir.Write("ward.json", R"({"model": "ward", "diffuse": [0.25, 0.15, 0.05],
                                                     "specular": [0.3, 0.25, 0.2], "shape": 0.05})");
  const std::string table = (dir.path() / "ward.binary").string();
  ASSERT_EQ(RunPhotorig("brdf convert " + spec + " " + table, dir.path() / "convert.log"), 0)
      << ReadText(dir.path() / "convert.log");
  const auto out = dir.path() / "fit";
  ASSERT_EQ(RunPhotorig("brdf fit " + table + " --samples 6000 --out " + out.string() + " --keep-table",
                        dir.path() / "fit.log"),
            0)
      << ReadText(dir.path() / "fit.log");
  const auto report = nlohmann::json::parse(ReadText(out / "report.json"));
  EXPECT_EQ(report["chosen"], "ward") << report["reason"];
  EXPECT_EQ(report["cells"].get<std::size_t>(), 909696u);  // MERL cells with both directions within 80 deg
  EXPECT_FALSE(report["poor_fit"].get<bool>());
  for (const nlohmann::json& c : report["candidates"]) {
    ASSERT_TRUE(c.contains("all_cells_log_rms")) << c["model"];
    if (c["model"] == "ward") {
      EXPECT_LT(c["all_cells_log_rms"].get<double>(), 0.01);
      EXPECT_EQ(c["at_bound"], "");
      EXPECT_EQ(c["implausible"], "");
    }
  }
  EXPECT_EQ(report["material"]["kind"], "table");
  EXPECT_TRUE(ReadText(out / "material.binary") == ReadText(table));
  EXPECT_NE(ReadText(dir.path() / "fit.log").find("over all"), std::string::npos);
  // A table has no deviations: the weighted loss is refused, and --keep-table needs --out.
  EXPECT_EQ(RunPhotorig("brdf fit " + table + " --loss weighted", dir.path() / "weighted.log"), 2);
  EXPECT_EQ(RunPhotorig("brdf fit " + table + " --keep-table", dir.path() / "keep.log"), 2);
}

}  // namespace
