// The gonioreflectometer end to end on the simulator: rig and pose
// validation, dry-run refusals (soft limits, separation, arms crossing), a run
// whose frames match the analytic BRDF at several poses, and every exit path
// leaving the arms stopped and the lamp off, or retried after a drive fault.

#include "photorig/daemon/plan.h"
#include "photorig/daemon/recipe.h"
#include "photorig/daemon/rig_devices.h"
#include "photorig/daemon/run.h"
#include "photorig/daemon/run_store.h"
#include "photorig/daemon/sequencer.h"
#include "photorig/drivers/motion/goniometer.h"
#include "photorig/sim/gonio.h"
#include "photorig/solvers/brdf/pose_plan.h"
#include "capture_fixtures.h"
#include "config_error_check.h"
#include "test_support.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include <cmath>
#include <filesystem>
#include <map>
#include <mutex>

namespace photorig::daemon {
namespace {

using photorig::testing::SourceDir;
using photorig::testing::TempDir;
using photorig::testing::WatchedDome;

constexpr double kAlbedo = 0.4, kRhoS = 0.15, kExponent = 20.0;
constexpr double kResponse = 1.5, kEPerDn = 4.0, kBlack = 64.0, kExposureUs = 4000.0;

// 32x32 px at 1 mm, a 12 mm sample disc, arms 15 deg apart at least, noise-free sensor.
std::string GonioRig(const std::string& faults = "") {
  std::string text = R"(rig: {name: gonio, kind: gonioreflectometer}
lights:
  driver: sim
  leds: [{id: 0, direction: [0, 0, 1], intensity: 1.0}]
camera: {driver: sim, width: 32, height: 32, pixel_pitch_mm: 1.0, bit_depth: 12, exposure_us: 4000}
motion:
  driver: sim
  time_scale: 50
  profile: {velocity_deg_s: 30, acceleration_deg_s2: 120}
  settle: {settle_ms: 5, poll_ms: 2, stall_window_ms: 100}
  axes:
    - {id: light_arm, min_deg: -80, max_deg: 80, home_deg: -60}
    - {id: camera_arm, min_deg: -80, max_deg: 80, home_deg: 60}
    - {id: sample_rotation, min_deg: -180, max_deg: 180}
  constraints:
    - {min_separation_deg: 15, axes: [light_arm, camera_arm]}
sim:
  seed: 5
  sensor: {response_e_per_us: 1.5, e_per_dn: 4.0, black_level_dn: 64, read_noise_e: 0, shot_noise: false}
  scene:
    shape: sample_plane
    radius_mm: 12
    albedo: {pattern: uniform, high: 0.4}
    brdf: {model: blinn_phong, rho_s: 0.15, exponent: 20}
)";
  if (!faults.empty()) text += "  faults: " + faults + "\n";
  return text;
}

std::string GonioRecipe(const std::string& poses) {
  return "recipe: {name: gonio, rig: rig.yaml}\ncapture:\n  exposure_us: 4000\n  steps:\n    - dark: {count: 1}\n"
         "    - poses:\n" + poses;
}

// Blinn-Phong in the sample frame (n = z) for arms in the x-z plane, written
// out independently of the renderer: f_r * cos(theta_i) at unit irradiance.
double ExpectedRadiance(double light_deg, double camera_deg) {
  const double ti = light_deg * M_PI / 180.0, to = camera_deg * M_PI / 180.0;
  const double hx = std::sin(ti) + std::sin(to), hz = std::cos(ti) + std::cos(to);
  const double n_dot_h = hz / std::hypot(hx, hz);
  const double f = kAlbedo / M_PI + kRhoS * (kExponent + 2.0) / (2.0 * M_PI) * std::pow(n_dot_h, kExponent);
  return f * std::cos(ti);
}

void ExpectConfigError(const std::string& rig_text, int line, int column, const std::string& fragment) {
  TempDir dir;
  const std::string path = dir.Write("rig.yaml", rig_text);
  photorig::testing::ExpectConfigErrorAt([&] { LoadRigConfig(path); }, path, line, column, fragment);
}

std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

// The capture of a pose list on the gonio rig (with `faults`), run through
// RunCapture with the rig's own devices; `lights` may stand in for the lamp.
struct GonioCapture {
  GonioCapture(TempDir& dir, const std::string& faults, const std::string& poses)
      : directory(dir.path()),
        rig(LoadRigConfig(dir.Write("rig.yaml", GonioRig(faults)))),
        recipe(LoadRecipe(dir.Write("r.yaml", GonioRecipe(poses)), rig)),
        devices(MakeRigDevices(rig, &recipe)) {}

  CaptureReport Run(drivers::LightController& lights, CaptureOptions options) {
    RunManifest header;
    header.width = header.height = 32;
    RunWriter writer((directory / "run").string(), header);
    options.motion = &devices.motion;
    options.motion_profile = rig.motion->profile;
    return RunCapture(CompileSteps(recipe, rig), rig.camera, lights, *devices.camera, writer, options);
  }

  std::filesystem::path directory;
  RigConfig rig;
  Recipe recipe;
  RigDevices devices;
};

TEST(Gonio, RigAndPoseErrorsNameTheirPosition) {
  ExpectConfigError(Replace(GonioRig(), "    - {id: sample_rotation, min_deg: -180, max_deg: 180}\n", ""), 12, 5,
                    "needs an axis 'sample_rotation'");
  ExpectConfigError(Replace(GonioRig(), "axes: [light_arm, camera_arm]", "axes: [light_arm, detector]"), 16, 50,
                    "no axis 'detector'");
  ExpectConfigError(Replace(GonioRig(), "{id: light_arm, min_deg: -80", "{id: light_arm, min_deg: 90"), 12, 7,
                    "needs min_deg < max_deg");
  ExpectConfigError(Replace(GonioRig(), "home_deg: -60", "home_deg: -90"), 12, 7,
                    "needs home_deg within [min_deg, max_deg]");
  // Homes closer than the arms may come: homing would drive them together.
  ExpectConfigError(Replace(GonioRig(), "home_deg: 60", "home_deg: -50"), 16, 7,
                    "homes (home_deg) are 10.000000 deg apart");
  ExpectConfigError(Replace(GonioRig(), "kind: gonioreflectometer", "kind: light_dome"), 7, 3,
                    "only a gonioreflectometer rig has motion");
  ExpectConfigError(Replace(GonioRig(), "  driver: sim\n  time_scale", "  driver: stepper\n  time_scale"), 7, 11,
                    "unknown motion driver 'stepper'");

  TempDir dir;
  const RigConfig rig = LoadRigConfig(dir.Write("rig.yaml", GonioRig()));
  const std::string both = dir.Write(
      "both.yaml", GonioRecipe("        list: [{light_arm_deg: 0, camera_arm_deg: 30}]\n        grid: {light_arm_deg: 0}\n"));
  photorig::testing::ExpectConfigErrorAt([&] { LoadRecipe(both, rig); }, both, 7, 9,
                                         "exactly one of 'list', 'grid' or 'plan'");
  const std::string typo = dir.Write("typo.yaml", GonioRecipe("        list: [{light_arm_deg: 0, camera_deg: 30}]\n"));
  photorig::testing::ExpectConfigErrorAt([&] { LoadRecipe(typo, rig); }, typo, 7, 35, "camera_deg");
}

TEST(Gonio, GridCompilesToPosesAndThePlanCountsTheMoves) {
  TempDir dir;
  const RigConfig rig = LoadRigConfig(dir.Write("rig.yaml", GonioRig()));
  const Recipe recipe = LoadRecipe(dir.Write(
      "r.yaml", GonioRecipe("        grid: {light_arm_deg: -30, camera_arm_deg: [0, 30], sample_rotation_deg: [0, 90]}\n")), rig);
  const auto steps = CompileSteps(recipe, rig);
  ASSERT_EQ(steps.size(), 5u);
  EXPECT_EQ(steps[1].kind, CaptureStep::Kind::kPose);
  EXPECT_EQ(steps[1].label, "0001_pose_l-30.0_c+0.0_r+0.0");
  ASSERT_TRUE(steps[4].pose.has_value());
  EXPECT_EQ(steps[4].pose->camera_arm_deg, 30.0);
  EXPECT_EQ(steps[4].pose->sample_rotation_deg, 90.0);
  EXPECT_EQ(steps[4].pattern.levels, std::vector<double>{1.0});
  PlanOptions options;
  options.step_overhead_ms = 0.0;
  const RunPlan plan = PlanRun(recipe, rig, steps, options);
  ASSERT_TRUE(plan.ok());
  // From the homes (light -60, camera +60): light to -30 and camera to 0;
  // camera to 30; camera back to 0 and rotation to 90; camera to 30. A
  // trapezoid from rest to rest over d takes d / v + v / a; each move adds
  // settle_ms (5 ms).
  auto move = [](double deg) { return deg / 30.0 + 30.0 / 120.0; };
  EXPECT_NEAR(plan.move_s, 4 * move(30) + move(60) + move(90) + 6 * 0.005, 1e-9);
  EXPECT_NEAR(plan.estimate.duration_s, plan.move_s + 5 * kExposureUs * 1e-6, 1e-9);
}

TEST(Gonio, DryRunAndRunRefuseBadPosesBeforeAnythingMoves) {
  struct Case {
    const char* poses;
    const char* fragment;
  };
  const Case cases[] = {
      {"        list: [{light_arm_deg: -30, camera_arm_deg: 85}]\n", "camera_arm target 85"},
      {"        list: [{light_arm_deg: -30, camera_arm_deg: 30}, {light_arm_deg: 20, camera_arm_deg: 30}]\n",
       "light_arm and camera_arm 10.0"},
      {"        list: [{light_arm_deg: -30, camera_arm_deg: 30}, {light_arm_deg: 40, camera_arm_deg: 0}]\n",
       "would have to pass each other"},
  };
  for (const Case& c : cases) {
    TempDir dir;
    const RigConfig rig = LoadRigConfig(dir.Write("rig.yaml", GonioRig()));
    const std::string path = dir.Write("r.yaml", GonioRecipe(c.poses));
    const Recipe recipe = LoadRecipe(path, rig);
    const RunPlan plan = PlanRun(recipe, rig, CompileSteps(recipe, rig));
    ASSERT_EQ(plan.errors.size(), 1u) << c.poses;
    EXPECT_NE(plan.errors[0].find(c.fragment), std::string::npos) << plan.errors[0];

    RunRequest request;
    request.recipe_path = path;
    request.output_directory = (dir.path() / "run").string();
    try {
      ExecuteRun(request);
      FAIL() << "run accepted " << c.poses;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(c.fragment), std::string::npos) << e.what();
    }
    EXPECT_FALSE(std::filesystem::exists(request.output_directory));  // nothing stored, nothing opened
  }
}

TEST(Gonio, FramesMatchTheAnalyticBrdfAtEachPose) {
  TempDir dir;
  dir.Write("rig.yaml", GonioRig());
  RunRequest request;
  request.recipe_path = dir.Write("r.yaml", GonioRecipe(R"(        list:
          - {light_arm_deg: -30, camera_arm_deg: 0}
          - {light_arm_deg: -30, camera_arm_deg: 30}
          - {light_arm_deg: -30, camera_arm_deg: 60}
          - {light_arm_deg: -30, camera_arm_deg: 30, sample_rotation_deg: 120}
          - {light_arm_deg: 10, camera_arm_deg: 50}
)"));
  request.output_directory = (dir.path() / "run").string();
  const RunOutcome outcome = ExecuteRun(request);
  ASSERT_EQ(outcome.capture.status, CaptureStatus::kComplete) << outcome.capture.reason;
  const RunManifest manifest = LoadRunManifest(request.output_directory);
  ASSERT_EQ(manifest.frames.size(), 6u);

  const double poses[][2] = {{-30, 0}, {-30, 30}, {-30, 60}, {-30, 30}, {10, 50}};
  double specular = 0.0, off_specular = 0.0;
  for (int k = 0; k < 5; ++k) {
    cv::Mat frame;
    const FrameRecord& record = manifest.frames[k + 1];
    // The manifest says where the arms were.
    EXPECT_EQ(record.kind, "pose");
    EXPECT_EQ(record.group, "poses");
    ASSERT_TRUE(record.pose.has_value()) << "pose " << k;
    EXPECT_EQ(record.pose->light_arm_deg, poses[k][0]);
    EXPECT_EQ(record.pose->camera_arm_deg, poses[k][1]);
    EXPECT_EQ(record.pose->sample_rotation_deg, k == 3 ? 120.0 : 0.0);
    LoadFrame(request.output_directory, record).convertTo(frame, CV_64F);
    const double radiance = ExpectedRadiance(poses[k][0], poses[k][1]);
    const double expected_dn = kBlack + radiance * kResponse * kExposureUs / kEPerDn;
    EXPECT_NEAR(frame.at<double>(16, 16), expected_dn, 0.5 + 1e-3 * expected_dn) << "pose " << k;
    // The disc (radius 12 mm, 1 mm pixels) foreshortened by the camera arm: 24 cos(theta_o) pixels across.
    int lit = 0;
    for (int col = 0; col < 32; ++col) lit += frame.at<double>(16, col) > kBlack + 0.5;
    EXPECT_NEAR(lit, 24.0 * std::cos(poses[k][1] * M_PI / 180.0), 1.01) << "pose " << k;
    if (k == 1) specular = frame.at<double>(16, 16);
    if (k == 0) off_specular = frame.at<double>(16, 16);
  }
  EXPECT_GT(specular - kBlack, 1.5 * (off_specular - kBlack));  // the highlight is where the mirror direction is
}

TEST(Gonio, FailureStopsTheArmsAndSwitchesTheLampOff) {
  TempDir dir;
  GonioCapture capture(dir, "{lights: {stuck_off_channels: [0]}}",
                       "        list: [{light_arm_deg: -40, camera_arm_deg: 20}, {light_arm_deg: -30, camera_arm_deg: 30}]\n");
  RigDevices& devices = capture.devices;
  WatchedDome dome("lamp", devices.world);
  const CaptureReport report = capture.Run(dome, {});
  EXPECT_EQ(report.status, CaptureStatus::kFailed);
  EXPECT_NE(report.reason.find("reads back"), std::string::npos) << report.reason;
  EXPECT_EQ(report.frames_written, 1);  // the dark frame
  // The arms reached the first pose, then every axis was stopped and closed; the lamp closed dark.
  const sim::ArmAngles arms = devices.world->arms();
  EXPECT_NEAR(arms.light_arm_deg, -40.0, 0.05);
  EXPECT_NEAR(arms.camera_arm_deg, 20.0, 0.05);
  for (const auto& axis : devices.motion.axes) {
    EXPECT_EQ(axis->state(), drivers::Motion::State::kClosed) << axis->id();
    EXPECT_GE(static_cast<sim::SimRotaryAxis&>(*axis).stops(), 2) << axis->id();  // StopAll and Close
  }
  EXPECT_EQ(dome.state(), drivers::LightController::State::kClosed);
  ASSERT_FALSE(dome.levels_at_close.empty());
  for (const auto& levels : dome.levels_at_close) EXPECT_EQ(levels, std::vector<double>{0.0});
}

// A drive that drops a move command leaves its axis in Fault: the retry must
// clear it and home every axis again before moving, then finish the run.
TEST(Gonio, ALostMoveCommandIsRetriedAfterClearingAndHoming) {
  TempDir dir;
  GonioCapture capture(dir, "{motion: {camera_arm: {refused_moves: [2]}}}",
                       "        list: [{light_arm_deg: -40, camera_arm_deg: 20}, {light_arm_deg: -30, camera_arm_deg: 30},\n"
                       "               {light_arm_deg: -20, camera_arm_deg: 40}]\n");
  RigDevices& devices = capture.devices;
  CaptureOptions options;
  options.retry.initial_backoff_ms = 1;
  const CaptureReport report = capture.Run(*devices.lights, options);
  ASSERT_EQ(report.status, CaptureStatus::kComplete) << report.reason;
  EXPECT_EQ(report.retries, 1);
  EXPECT_EQ(report.frames_written, 4);  // dark + three poses, none twice
  const sim::ArmAngles arms = devices.world->arms();
  EXPECT_NEAR(arms.light_arm_deg, -20.0, 0.05);
  EXPECT_NEAR(arms.camera_arm_deg, 40.0, 0.05);
  for (const auto& axis : devices.motion.axes)
    EXPECT_EQ(static_cast<sim::SimRotaryAxis&>(*axis).homings(), 2) << axis->id();  // at the start and after the fault
}

TEST(Gonio, MotionFaultsNameAnAxisOfTheRig) {
  ExpectConfigError(GonioRig("{motion: {tilt_arm: {refused_moves: [1]}}}"), 25, 31, "no axis 'tilt_arm'");
}

// The rig with a sample changer holding a reference target of albedo 0.9 in slot 90.
std::string GonioRigWithTarget(const std::string& target_pose = "{light_arm_deg: 0, camera_arm_deg: 45, "
                                                                 "sample_changer_deg: 90}") {
  return Replace(Replace(GonioRig(), "    - {id: sample_rotation, min_deg: -180, max_deg: 180}\n",
                         "    - {id: sample_rotation, min_deg: -180, max_deg: 180}\n"
                         "    - {id: sample_changer, min_deg: -5, max_deg: 95}\n"),
                 "sim:\n", "reference_target: {albedo: 0.9, pose: " + target_pose + "}\nsim:\n");
}

TEST(Gonio, BracketsRepeatsAndTheReferenceTargetCompileToSteps) {
  TempDir dir;
  const RigConfig rig = LoadRigConfig(dir.Write("rig.yaml", GonioRigWithTarget()));
  ASSERT_TRUE(rig.reference_target.has_value());
  EXPECT_EQ(rig.reference_target->albedo, 0.9);
  const Recipe recipe = LoadRecipe(
      dir.Write("r.yaml", "recipe: {name: gonio, rig: rig.yaml}\ncapture:\n  exposure_us: 4000\n  steps:\n"
                          "    - dark: {count: 2, exposures_us: [1000, 4000]}\n"
                          "    - reference_target: {count: 2, exposures_us: [1000]}\n"
                          "    - poses: {exposures_us: [1000, 4000], count: 2, list: [{light_arm_deg: -30, "
                          "camera_arm_deg: 30}]}\n"),
      rig);
  const auto steps = CompileSteps(recipe, rig);
  ASSERT_EQ(steps.size(), 10u);
  EXPECT_EQ(steps[0].label, "0000_dark_e1000");
  EXPECT_EQ(steps[3].exposure_us, 4000.0);
  // The target: at its pose, the changer on its slot.
  EXPECT_EQ(steps[4].group, "reference_target");
  EXPECT_EQ(steps[4].label, "0004_target_l+0.0_c+45.0_r+0.0_e1000");
  ASSERT_TRUE(steps[5].pose && steps[5].pose->sample_changer_deg);
  EXPECT_EQ(*steps[5].pose->sample_changer_deg, 90.0);
  // A pose naming no slot holds the sample; each exposure `count` times, as listed.
  EXPECT_EQ(steps[6].label, "0006_pose_l-30.0_c+30.0_r+0.0_e1000");
  ASSERT_TRUE(steps[6].pose && steps[6].pose->sample_changer_deg);
  EXPECT_EQ(*steps[6].pose->sample_changer_deg, 0.0);
  const double exposures[] = {1000, 1000, 4000, 4000};
  for (int k = 0; k < 4; ++k) EXPECT_EQ(steps[6 + k].exposure_us, exposures[k]) << k;
  EXPECT_TRUE(PlanRun(recipe, rig, steps).ok());

  // Refusals, each at its line.
  const std::string no_target = dir.Write("plain.yaml", GonioRig());
  const RigConfig plain = LoadRigConfig(no_target);
  const std::string asks = dir.Write("asks.yaml", "recipe: {name: gonio, rig: rig.yaml}\ncapture:\n  steps:\n"
                                                  "    - dark: {count: 2}\n    - reference_target: {count: 1}\n");
  photorig::testing::ExpectConfigErrorAt([&] { CompileSteps(LoadRecipe(asks, plain), plain); }, asks, 5, 7,
                                         "names no reference_target");
  const std::string twice = dir.Write(
      "twice.yaml", GonioRecipe("        exposures_us: [1000, 1000]\n        list: [{light_arm_deg: 0, camera_arm_deg: 30}]\n"));
  photorig::testing::ExpectConfigErrorAt([&] { LoadRecipe(twice, rig); }, twice, 7, 30, "listed twice");
  ExpectConfigError(Replace(GonioRigWithTarget(), "albedo: 0.9", "albedo: 1.5"), 18, 28, "must lie in [0.01, 1]");
  ExpectConfigError(GonioRigWithTarget("{light_arm_deg: 0, camera_arm_deg: 10, sample_changer_deg: 90}"), 18, 39,
                    "below the minimum 15");
  ExpectConfigError(GonioRigWithTarget("{light_arm_deg: 0, camera_arm_deg: 45, sample_changer_deg: 0}"), 18, 98,
                    "the sample's slot");
  ExpectConfigError(GonioRigWithTarget("{light_arm_deg: 0, camera_arm_deg: 45}"), 18, 39,
                    "give sample_changer_deg");
}

// The simulator shows the target in its slot: a Lambertian plane of its albedo.
TEST(Gonio, TheSimulatedReferenceTargetIsLambertianOfItsAlbedo) {
  TempDir dir;
  dir.Write("rig.yaml", GonioRigWithTarget());
  RunRequest request;
  request.recipe_path = dir.Write(
      "r.yaml", "recipe: {name: gonio, rig: rig.yaml}\ncapture:\n  exposure_us: 4000\n  steps:\n"
                "    - dark: {count: 1}\n    - reference_target: {count: 1}\n"
                "    - poses: {list: [{light_arm_deg: -30, camera_arm_deg: 30}]}\n");
  request.output_directory = (dir.path() / "run").string();
  const RunOutcome outcome = ExecuteRun(request);
  ASSERT_EQ(outcome.capture.status, CaptureStatus::kComplete) << outcome.capture.reason;
  const RunManifest manifest = LoadRunManifest(request.output_directory);
  ASSERT_EQ(manifest.frames.size(), 3u);
  ASSERT_TRUE(manifest.reference_albedo.has_value());
  EXPECT_EQ(*manifest.reference_albedo, 0.9);
  EXPECT_EQ(manifest.frames[1].group, "reference_target");
  cv::Mat target, sample;
  LoadFrame(request.output_directory, manifest.frames[1]).convertTo(target, CV_64F);
  LoadFrame(request.output_directory, manifest.frames[2]).convertTo(sample, CV_64F);
  // Light on the normal: L = 0.9 / pi at unit irradiance.
  EXPECT_NEAR(target.at<double>(16, 16), kBlack + 0.9 / M_PI * kResponse * kExposureUs / kEPerDn, 0.51);
  // After the target, the changer brings the sample back.
  const double expected_dn = kBlack + ExpectedRadiance(-30, 30) * kResponse * kExposureUs / kEPerDn;
  EXPECT_NEAR(sample.at<double>(16, 16), expected_dn, 0.5 + 1e-3 * expected_dn);
}

// A pose plan on the test rig (arms to +-80 deg, 15 deg apart, homes -60 and +60).
std::string PlanStep(const std::string& plan) { return "        plan: " + plan + "\n"; }

TEST(Gonio, PlanStepPlansForTheRigAndDryRunListsWhatItRefused) {
  TempDir dir;
  const RigConfig rig = LoadRigConfig(dir.Write("rig.yaml", GonioRig()));
  const std::string path = dir.Write(
      "r.yaml", GonioRecipe(PlanStep("{theta_h_deg: {min: 0, max: 60, steps: 7}, theta_d_deg: {min: 5, max: 75, steps: 8}}")));
  const Recipe recipe = LoadRecipe(path, rig);
  const auto steps = CompileSteps(recipe, rig);
  // The same plan as the solver makes for these arms.
  solvers::brdf::SamplingSpec spec;
  spec.theta_h_steps = 7;
  spec.theta_d_min_deg = 5;
  spec.theta_d_max_deg = 75;
  spec.theta_d_steps = 8;
  const solvers::brdf::PosePlan expected =
      solvers::brdf::PlanPoses(solvers::brdf::UniformHalfDiffGrid(spec), *config::GonioArmsOf(*rig.motion));
  ASSERT_EQ(steps.size(), 1 + expected.poses.size());
  ASSERT_GT(expected.refused.size(), 0u);
  for (std::size_t i = 0; i < expected.poses.size(); ++i) {
    ASSERT_TRUE(steps[i + 1].pose.has_value());
    EXPECT_NEAR(steps[i + 1].pose->light_arm_deg, expected.poses[i].arms.light_arm_deg, 1e-12);
    EXPECT_NEAR(steps[i + 1].pose->camera_arm_deg, expected.poses[i].arms.camera_arm_deg, 1e-12);
  }
  const RunPlan plan = PlanRun(recipe, rig, steps);
  EXPECT_TRUE(plan.ok()) << plan.errors.front();
  // Every refused configuration is listed with its reason and where the plan is.
  int refused = 0, apart = 0, limits = 0, grazing = 0;
  for (const std::string& w : plan.warnings) {
    EXPECT_EQ(w.rfind(path + ":6: pose plan: ", 0), 0u) << w;
    refused += w.find("refused") != std::string::npos;
    apart += w.find("closer than 15.00") != std::string::npos;
    limits += w.find("beyond its limits [-80.00, 80.00]") != std::string::npos;
    grazing += w.find("grazing") != std::string::npos;
  }
  EXPECT_EQ(refused, static_cast<int>(expected.refused.size()));
  EXPECT_GT(apart, 0);   // theta_d = 5 deg: arms 10 deg apart
  EXPECT_GT(limits, 0);  // theta_h + theta_d beyond 80 deg
  EXPECT_EQ(grazing, expected.grazing > 0 ? 1 : 0);
}

TEST(Gonio, PlanStepErrorsNameTheirPosition) {
  struct Case {
    const char* plan;
    int line, column;
    const char* fragment;
  };
  const Case cases[] = {
      // Every configuration beyond the arms: an error, with the first reason.
      {"{theta_h_deg: 60, theta_d_deg: {min: 40, max: 60, steps: 3}}", 7, 15,
       "none of the 3 requested configurations is reachable by the arms (first: theta_h 60.00 theta_d 40.00"},
      {"{theta_h_deg: 30, theta_d_deg: 30, phi_d_deg: 90}", 7, 15, "out of the arms' plane"},
      {"{theta_h: 30}", 7, 16, "theta_h"},
      {"{theta_h_deg: {min: 50, max: 10, steps: 3}}", 7, 15, "ranges must be ordered"},
      {"{theta_h_deg: {min: 0, max: 10, steps: 0}}", 7, 54, "must be within [1, 1000]"},
  };
  for (const Case& c : cases) {
    TempDir dir;
    const RigConfig rig = LoadRigConfig(dir.Write("rig.yaml", GonioRig()));
    const std::string path = dir.Write("r.yaml", GonioRecipe(PlanStep(c.plan)));
    photorig::testing::ExpectConfigErrorAt([&] { LoadRecipe(path, rig); }, path, c.line, c.column, c.fragment);
  }
  // Two ways of giving poses at once.
  TempDir dir;
  const RigConfig rig = LoadRigConfig(dir.Write("rig.yaml", GonioRig()));
  const std::string both = dir.Write(
      "r.yaml", GonioRecipe(PlanStep("{theta_h_deg: 0}") + "        list: [{light_arm_deg: -30, camera_arm_deg: 30}]\n"));
  photorig::testing::ExpectConfigErrorAt([&] { LoadRecipe(both, rig); }, both, 7, 9, "exactly one of 'list', 'grid' or 'plan'");
}

// Homing and every planned move through the simulated goniometer: the arms'
// positions, read at every poll of every move, never come closer than the
// rig's separation.
TEST(Gonio, HomingAndEveryPlannedMoveKeepTheArmsApart) {
  TempDir dir;
  const RigConfig rig = LoadRigConfig(dir.Write("rig.yaml", GonioRig()));
  const Recipe recipe = LoadRecipe(
      dir.Write("r.yaml", GonioRecipe(PlanStep("{theta_h_deg: {min: 0, max: 60, steps: 5}, theta_d_deg: {min: 8, max: 72, steps: 5}}"))),
      rig);
  const auto steps = CompileSteps(recipe, rig);
  ASSERT_GT(steps.size(), 10u);
  std::mutex mutex;
  std::map<std::string, double> at;  // rig degrees
  double closest = 1e9;
  int readings = 0;
  std::vector<std::unique_ptr<sim::SimRotaryAxis>> axes;
  std::vector<drivers::Motion*> motions;
  for (const AxisConfig& axis : rig.motion->axes) {
    sim::SimAxisOptions options = rig.motion->sim_axis;
    // Power on away from home, each arm on its own side.
    options.power_on_deg = axis.id == "light_arm" ? 40.0 : axis.id == "camera_arm" ? -30.0 : 0.0;
    at[axis.id] = axis.limits.home_deg + options.power_on_deg;
    axes.push_back(std::make_unique<sim::SimRotaryAxis>(
        axis.id, axis.limits, rig.motion->settle, options, [&, id = axis.id, home = axis.limits.home_deg](double deg) {
          std::lock_guard lock(mutex);
          at[id] = deg + home;
          closest = std::min(closest, at["camera_arm"] - at["light_arm"]);
          ++readings;
        }));
    motions.push_back(axes.back().get());
  }
  drivers::Goniometer goniometer(motions, rig.motion->constraints);
  for (drivers::Motion* m : motions) ASSERT_TRUE(m->Open().ok());
  const Status homed = goniometer.HomeAll();
  ASSERT_TRUE(homed.ok()) << homed.ToString();
  for (const CaptureStep& step : steps) {
    if (!step.pose) continue;
    const Status moved = goniometer.MoveTo(PoseTargets(*step.pose), rig.motion->profile);
    ASSERT_TRUE(moved.ok()) << step.label << ": " << moved.ToString();
    EXPECT_NEAR(at["light_arm"], step.pose->light_arm_deg, 0.05) << step.label;
    EXPECT_NEAR(at["camera_arm"], step.pose->camera_arm_deg, 0.05) << step.label;
  }
  EXPECT_GT(readings, 10 * static_cast<int>(steps.size()));  // the sweeps were watched, not just their ends
  EXPECT_GE(closest, 15.0 - rig.motion->settle.tolerance_deg) << "arms came within " << closest << " deg";
  EXPECT_TRUE(goniometer.CloseAll().ok());
}

TEST(Gonio, PlanStepRunsThroughTheSequencer) {
  TempDir dir;
  dir.Write("rig.yaml", GonioRig());
  RunRequest request;
  request.recipe_path = dir.Write(
      "r.yaml", GonioRecipe(PlanStep("{theta_h_deg: {min: 0, max: 40, steps: 3}, theta_d_deg: {min: 10, max: 40, steps: 3}}")));
  request.output_directory = (dir.path() / "run").string();
  const RunOutcome outcome = ExecuteRun(request);
  ASSERT_EQ(outcome.capture.status, CaptureStatus::kComplete) << outcome.capture.reason;
  const RunManifest manifest = LoadRunManifest(request.output_directory);
  ASSERT_EQ(manifest.frames.size(), 1u + 9u);
  // Each frame's arms give back a configuration of the plan.
  for (std::size_t k = 1; k < manifest.frames.size(); ++k) {
    ASSERT_TRUE(manifest.frames[k].pose.has_value());
    const auto d = solvers::brdf::ArmDirections({manifest.frames[k].pose->light_arm_deg,
                                                 manifest.frames[k].pose->camera_arm_deg, 0.0});
    const solvers::brdf::HalfDiff hd = solvers::brdf::ToHalfDiff(d.wi, d.wo);
    const double th = hd.theta_h * 180 / M_PI, td = hd.theta_d * 180 / M_PI;
    EXPECT_NEAR(std::remainder(th, 20.0), 0.0, 1e-6) << th;
    EXPECT_NEAR(std::remainder(td - 10.0, 15.0), 0.0, 1e-6) << td;
  }
}

TEST(Gonio, ShippedRecipeDryRunsClean) {
  const std::string path = SourceDir() + "/config/recipes/gonio-sample.yaml";
  const RigConfig rig = LoadRigConfig(RecipeRigPath(path, ""));
  const Recipe recipe = LoadRecipe(path, rig);
  const auto steps = CompileSteps(recipe, rig);
  const RunPlan plan = PlanRun(recipe, rig, steps);
  EXPECT_TRUE(plan.ok()) << (plan.errors.empty() ? "" : plan.errors[0]);
  EXPECT_EQ(steps.size(), 13u);
  EXPECT_GT(plan.move_s, 0.0);
}

}  // namespace
}  // namespace photorig::daemon
