// The gonioreflectometer end to end on the simulator: rig and pose
// validation, dry-run refusals (soft limits, separation, arms crossing), a run
// whose frames match the analytic BRDF at several poses, and every exit path
// leaving the arms stopped and the lamp off, or retried after a drive fault.

#include "photorig/daemon/pipelines/adaptive_poses.h"
#include "photorig/daemon/pipelines/brdf_measurement.h"
#include "photorig/daemon/capture/plan.h"
#include "photorig/config/recipe.h"
#include "photorig/config/solve_requests.h"
#include "photorig/daemon/capture/internal/rig_devices.h"
#include "photorig/daemon/service/run.h"
#include "photorig/daemon/capture/run_store.h"
#include "photorig/daemon/capture/sequencer.h"
#include "photorig/drivers/motion/goniometer.h"
#include "photorig/sim/gonio.h"
#include "photorig/solvers/brdf/fit.h"
#include "photorig/solvers/brdf/half_diff.h"
#include "photorig/solvers/brdf/pose_plan.h"
#include "capture_fixtures.h"
#include "config_error_check.h"
#include "test_support.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <map>
#include <mutex>

namespace photorig::daemon {
namespace {

using photorig::testing::ReadText;
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
  photorig::testing::ExpectConfigErrorAt([&] { config::LoadRigConfig(path); }, path, line, column, fragment);
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
        rig(config::LoadRigConfig(dir.Write("rig.yaml", GonioRig(faults)))),
        recipe(config::LoadRecipe(dir.Write("r.yaml", GonioRecipe(poses)), rig)),
        devices(MakeRigDevices(rig, &recipe)) {}

  CaptureReport Run(drivers::LightController& lights, CaptureOptions options) {
    RunManifest header;
    header.width = header.height = 32;
    RunWriter writer((directory / "run").string(), header);
    options.motion = &devices.motion;
    options.motion_profile = rig.motion->profile;
    return RunCapture(config::CompileSteps(recipe, rig), rig.camera, lights, *devices.camera, writer, options);
  }

  std::filesystem::path directory;
  config::RigConfig rig;
  config::Recipe recipe;
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
  const config::RigConfig rig = config::LoadRigConfig(dir.Write("rig.yaml", GonioRig()));
  const std::string both = dir.Write(
      "both.yaml", GonioRecipe("        list: [{light_arm_deg: 0, camera_arm_deg: 30}]\n        grid: {light_arm_deg: 0}\n"));
  photorig::testing::ExpectConfigErrorAt([&] { config::LoadRecipe(both, rig); }, both, 7, 9,
                                         "exactly one of 'list', 'grid' or 'plan'");
  const std::string typo = dir.Write("typo.yaml", GonioRecipe("        list: [{light_arm_deg: 0, camera_deg: 30}]\n"));
  photorig::testing::ExpectConfigErrorAt([&] { config::LoadRecipe(typo, rig); }, typo, 7, 35, "camera_deg");
}

TEST(Gonio, GridCompilesToPosesAndThePlanCountsTheMoves) {
  TempDir dir;
  const config::RigConfig rig = config::LoadRigConfig(dir.Write("rig.yaml", GonioRig()));
  const config::Recipe recipe = config::LoadRecipe(dir.Write(
      "r.yaml", GonioRecipe("        grid: {light_arm_deg: -30, camera_arm_deg: [0, 30], sample_rotation_deg: [0, 90]}\n")), rig);
  const auto steps = config::CompileSteps(recipe, rig);
  ASSERT_EQ(steps.size(), 5u);
  EXPECT_EQ(steps[1].kind, config::CaptureStep::Kind::kPose);
  EXPECT_EQ(steps[1].label, "0001_pose_l-30.0_c+0.0_r+0.0");
  ASSERT_TRUE(steps[4].pose.has_value());
  EXPECT_EQ(steps[4].pose->camera_arm_deg, 30.0);
  EXPECT_EQ(steps[4].pose->sample_rotation_deg, 90.0);
  EXPECT_EQ(steps[4].pattern->levels, std::vector<double>{1.0});
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
    const config::RigConfig rig = config::LoadRigConfig(dir.Write("rig.yaml", GonioRig()));
    const std::string path = dir.Write("r.yaml", GonioRecipe(c.poses));
    const config::Recipe recipe = config::LoadRecipe(path, rig);
    const RunPlan plan = PlanRun(recipe, rig, config::CompileSteps(recipe, rig));
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
    EXPECT_EQ(record.kind, config::CaptureStep::Kind::kPose);
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
  const config::RigConfig rig = config::LoadRigConfig(dir.Write("rig.yaml", GonioRigWithTarget()));
  ASSERT_TRUE(rig.reference_target.has_value());
  EXPECT_EQ(rig.reference_target->albedo, 0.9);
  const config::Recipe recipe = config::LoadRecipe(
      dir.Write("r.yaml", "recipe: {name: gonio, rig: rig.yaml}\ncapture:\n  exposure_us: 4000\n  steps:\n"
                          "    - dark: {count: 2, exposures_us: [1000, 4000]}\n"
                          "    - reference_target: {count: 2, exposures_us: [1000]}\n"
                          "    - poses: {exposures_us: [1000, 4000], count: 2, list: [{light_arm_deg: -30, "
                          "camera_arm_deg: 30}]}\n"),
      rig);
  const auto steps = config::CompileSteps(recipe, rig);
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
  const config::RigConfig plain = config::LoadRigConfig(no_target);
  const std::string asks = dir.Write("asks.yaml", "recipe: {name: gonio, rig: rig.yaml}\ncapture:\n  steps:\n"
                                                  "    - dark: {count: 2}\n    - reference_target: {count: 1}\n");
  photorig::testing::ExpectConfigErrorAt([&] { config::CompileSteps(config::LoadRecipe(asks, plain), plain); }, asks, 5, 7,
                                         "names no reference_target");
  const std::string twice = dir.Write(
      "twice.yaml", GonioRecipe("        exposures_us: [1000, 1000]\n        list: [{light_arm_deg: 0, camera_arm_deg: 30}]\n"));
  photorig::testing::ExpectConfigErrorAt([&] { config::LoadRecipe(twice, rig); }, twice, 7, 30, "listed twice");
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
  const config::RigConfig rig = config::LoadRigConfig(dir.Write("rig.yaml", GonioRig()));
  const std::string path = dir.Write(
      "r.yaml", GonioRecipe(PlanStep("{theta_h_deg: {min: 0, max: 60, steps: 7}, theta_d_deg: {min: 5, max: 75, steps: 8}}")));
  const config::Recipe recipe = config::LoadRecipe(path, rig);
  const auto steps = config::CompileSteps(recipe, rig);
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
    const config::RigConfig rig = config::LoadRigConfig(dir.Write("rig.yaml", GonioRig()));
    const std::string path = dir.Write("r.yaml", GonioRecipe(PlanStep(c.plan)));
    photorig::testing::ExpectConfigErrorAt([&] { config::LoadRecipe(path, rig); }, path, c.line, c.column, c.fragment);
  }
  // Two ways of giving poses at once.
  TempDir dir;
  const config::RigConfig rig = config::LoadRigConfig(dir.Write("rig.yaml", GonioRig()));
  const std::string both = dir.Write(
      "r.yaml", GonioRecipe(PlanStep("{theta_h_deg: 0}") + "        list: [{light_arm_deg: -30, camera_arm_deg: 30}]\n"));
  photorig::testing::ExpectConfigErrorAt([&] { config::LoadRecipe(both, rig); }, both, 7, 9, "exactly one of 'list', 'grid' or 'plan'");
}

// The rig's axes as simulated drives that record the position each reports
// at every poll of every move, and pass it on to `world` (when given, so the
// simulated frames see the arms where they are); the closest the arms came.
struct WatchedArms {
  // `away`: each arm powers on away from its home, on its own side.
  WatchedArms(const config::RigConfig& rig, std::shared_ptr<sim::World> world, bool away) {
    std::vector<drivers::Motion*> motions;
    for (const config::AxisConfig& axis : rig.motion->axes) {
      sim::SimAxisOptions options = rig.motion->sim_axis;
      if (away) options.power_on_deg = axis.id == "light_arm" ? 40.0 : axis.id == "camera_arm" ? -30.0 : 0.0;
      at[axis.id] = axis.limits.home_deg + options.power_on_deg;
      motion.axes.push_back(std::make_unique<sim::SimRotaryAxis>(
          axis.id, axis.limits, rig.motion->settle, options,
          [this, world, id = axis.id, home = axis.limits.home_deg](double deg) {
            if (world) world->SetArm(id, deg + home);
            std::lock_guard lock(mutex);
            at[id] = deg + home;
            closest = std::min(closest, at["camera_arm"] - at["light_arm"]);
            ++readings;
          }));
      motions.push_back(motion.axes.back().get());
    }
    motion.goniometer = std::make_unique<drivers::Goniometer>(motions, rig.motion->constraints);
  }

  MotionRig motion;
  std::mutex mutex;
  std::map<std::string, double> at;  // rig degrees
  double closest = 1e9;
  int readings = 0;
};

// Homing and every planned move through the simulated goniometer: the arms'
// positions, read at every poll of every move, never come closer than the
// rig's separation.
TEST(Gonio, HomingAndEveryPlannedMoveKeepTheArmsApart) {
  TempDir dir;
  const config::RigConfig rig = config::LoadRigConfig(dir.Write("rig.yaml", GonioRig()));
  const config::Recipe recipe = config::LoadRecipe(
      dir.Write("r.yaml", GonioRecipe(PlanStep("{theta_h_deg: {min: 0, max: 60, steps: 5}, theta_d_deg: {min: 8, max: 72, steps: 5}}"))),
      rig);
  const auto steps = config::CompileSteps(recipe, rig);
  ASSERT_GT(steps.size(), 10u);
  WatchedArms arms(rig, nullptr, true);
  drivers::Goniometer& goniometer = *arms.motion.goniometer;
  for (auto& m : arms.motion.axes) ASSERT_TRUE(m->Open().ok());
  const Status homed = goniometer.HomeAll();
  ASSERT_TRUE(homed.ok()) << homed.ToString();
  for (const config::CaptureStep& step : steps) {
    if (!step.pose) continue;
    const Status moved = goniometer.MoveTo(PoseTargets(*step.pose), rig.motion->profile);
    ASSERT_TRUE(moved.ok()) << step.label << ": " << moved.ToString();
    EXPECT_NEAR(arms.at["light_arm"], step.pose->light_arm_deg, 0.05) << step.label;
    EXPECT_NEAR(arms.at["camera_arm"], step.pose->camera_arm_deg, 0.05) << step.label;
  }
  EXPECT_GT(arms.readings, 10 * static_cast<int>(steps.size()));  // the sweeps were watched, not just their ends
  EXPECT_GE(arms.closest, 15.0 - rig.motion->settle.tolerance_deg) << "arms came within " << arms.closest << " deg";
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
  const config::RigConfig rig = config::LoadRigConfig(config::RecipeRigPath(path, ""));
  const config::Recipe recipe = config::LoadRecipe(path, rig);
  const auto steps = config::CompileSteps(recipe, rig);
  const RunPlan plan = PlanRun(recipe, rig, steps);
  EXPECT_TRUE(plan.ok()) << (plan.errors.empty() ? "" : plan.errors[0]);
  EXPECT_EQ(steps.size(), 13u);
  EXPECT_GT(plan.move_s, 0.0);
}

// Adaptive plans. The test rig with the reference target and a noisy sensor
// (the measurement between passes reads the noise from the darks), and a
// near-mirror sample: Blinn-Phong e = 2000, a lobe about 2 deg wide, which a
// plan every 10 deg in theta_h sees only at its peak.
constexpr double kMirrorExponent = 2000.0;
// k_s in solvers/brdf's normalisation for the simulator's rho_s 0.15 (docs/brdf.md).
const double kMirrorKs = 0.15 * 4.0 * (std::pow(2.0, -kMirrorExponent / 2.0) + kMirrorExponent) / (kMirrorExponent + 4.0);

std::string NoisyGonioRigWithTarget() {
  return Replace(GonioRigWithTarget(), "read_noise_e: 0, shot_noise: false", "read_noise_e: 6, shot_noise: true");
}

const char* const kDarksAndTarget = "    - dark: {count: 2, exposures_us: [100, 4000]}\n"
                                    "    - reference_target: {count: 1, exposures_us: [4000]}\n";

// The coarse plan (theta_h 0, 10, 20 by theta_d 15, 30, 45 deg) with `adaptive`, after `before` and before `after`.
std::string AdaptiveRecipe(const std::string& adaptive = "{passes: 2, added_poses: 4}",
                           const std::string& before = kDarksAndTarget, const std::string& after = "") {
  return "recipe: {name: adaptive, rig: rig.yaml}\n"
         "sample:\n"
         "  sim_scene: {shape: sample_plane, radius_mm: 12, albedo: {pattern: uniform, high: 0.4},\n"
         "              brdf: {model: blinn_phong, rho_s: 0.15, exponent: 2000}}\n"
         "capture:\n  exposure_us: 4000\n  steps:\n" +
         before +
         "    - poses:\n"
         "        exposures_us: [100, 4000]\n"
         "        plan:\n"
         "          theta_h_deg: {min: 0, max: 20, steps: 3}\n"
         "          theta_d_deg: {min: 15, max: 45, steps: 3}\n"
         "          adaptive: " + adaptive + "\n" + after;
}

// An adaptive recipe captured through RunCapture with the rig's own camera and
// world, arms watched at every poll, and the passes planned by AdaptivePoses.
struct AdaptiveCapture {
  explicit AdaptiveCapture(TempDir& dir)
      : directory(dir.path() / "run"),
        rig(config::LoadRigConfig(dir.Write("rig.yaml", NoisyGonioRigWithTarget()))),
        recipe(config::LoadRecipe(dir.Write("r.yaml", AdaptiveRecipe()), rig)),
        devices(MakeRigDevices(rig, &recipe)),
        arms(rig, devices.world, false),
        passes(recipe, *config::AdaptivePlanGroup(recipe), rig) {}

  RunManifest Header() const { return ManifestHeaderFor(rig); }

  CaptureReport Run(RunWriter& writer, drivers::LightController& lights, CaptureOptions options = {}) {
    options.motion = &arms.motion;
    options.motion_profile = rig.motion->profile;
    options.health = rig.health;
    options.leds = rig.lights.leds;
    options.next_pass = [this](const std::vector<config::CaptureStep>& steps, std::size_t ended, const RunWriter& run) {
      return passes.NextPass(steps, ended, run);
    };
    return RunCapture(config::CompileSteps(recipe, rig), rig.camera, lights, *devices.camera, writer, options);
  }

  std::filesystem::path directory;
  config::RigConfig rig;
  config::Recipe recipe;
  RigDevices devices;
  WatchedArms arms;
  AdaptivePoses passes;
};

double ThetaHDeg(const config::GonioPose& pose) {
  const auto d = solvers::brdf::ArmDirections({pose.light_arm_deg, pose.camera_arm_deg, pose.sample_rotation_deg});
  return solvers::brdf::ToHalfDiff(d.wi, d.wo).theta_h * 180.0 / M_PI;
}

// The distinct poses of the run's pose frames, by pass.
std::map<int, std::vector<config::GonioPose>> PosesByPass(const RunManifest& manifest) {
  std::map<int, std::vector<config::GonioPose>> by_pass;
  for (const FrameRecord& r : manifest.frames) {
    if (r.group != "poses" || r.exposure_us != 100.0) continue;  // one frame per pose
    by_pass[r.pass].push_back(*r.pose);
  }
  return by_pass;
}

solvers::brdf::FitSummary FitBlinnPhong(const std::string& directory, RunManifest manifest, int max_pass) {
  std::erase_if(manifest.frames, [&](const FrameRecord& r) { return r.pass > max_pass; });
  const BrdfMeasurement m = MeasureBrdf(directory, manifest);
  EXPECT_TRUE(m.IsSolutionUsable()) << m.message;
  return solvers::brdf::FitModel(solvers::brdf::Model::kBlinnPhong, m.samples);
}

TEST(Gonio, AnAdaptivePlanAddsPosesOnTheLobesFlanksAndTheFitUsesThemAll) {
  TempDir dir;
  AdaptiveCapture capture(dir);
  RunWriter writer(capture.directory.string(), capture.Header());
  const CaptureReport report = capture.Run(writer, *capture.devices.lights);
  ASSERT_EQ(report.status, CaptureStatus::kComplete) << report.reason;

  // Two passes of four poses each, at both exposures: 4 darks, 1 target frame, 9 coarse poses, 8 added.
  const auto& passes = capture.passes.passes();
  ASSERT_EQ(passes.size(), 2u);
  for (const AdaptivePassReport& pass : passes) {
    EXPECT_EQ(pass.poses_added, 4) << pass.pass;
    EXPECT_EQ(pass.frames_added, 8) << pass.pass;
    EXPECT_EQ(pass.stopped, "") << pass.pass;
  }
  EXPECT_EQ(passes[0].samples, 9);
  EXPECT_EQ(passes[1].samples, 13);
  EXPECT_EQ(report.steps_total, 4 + 1 + 2 * (9 + 8));
  EXPECT_EQ(report.frames_written, report.steps_total);
  const std::map<int, std::vector<config::GonioPose>> by_pass = PosesByPass(writer.manifest());
  ASSERT_EQ(by_pass.size(), 3u);
  EXPECT_EQ(by_pass.at(0).size(), 9u);
  // The lobe falls off between the peak and theta_h 10 deg: the first pass
  // splits that interval in every theta_d row, the second the half nearer the peak.
  auto count_at = [&](int pass, double theta_h_deg) {
    return std::count_if(by_pass.at(pass).begin(), by_pass.at(pass).end(),
                         [&](const config::GonioPose& p) { return std::abs(ThetaHDeg(p) - theta_h_deg) < 1e-6; });
  };
  EXPECT_EQ(count_at(1, 5.0), 3);
  EXPECT_EQ(count_at(2, 2.5), 3);

  // Every move, added ones too, kept the arms apart, watched at every poll.
  EXPECT_GT(capture.arms.readings, 100);
  EXPECT_GE(capture.arms.closest, 15.0 - capture.rig.motion->settle.tolerance_deg)
      << "arms came within " << capture.arms.closest << " deg";

  writer.Finish(report.ToStopRecord());
  EXPECT_EQ(VerifyRun(capture.directory.string()), std::vector<std::string>{});
  // The pass each frame came from is in the stored manifest.
  const RunManifest stored = LoadRunManifest(capture.directory.string());
  EXPECT_EQ(PosesByPass(stored).at(2).size(), 4u);

  // The fit of every frame recovers the lobe; the coarse poses alone see its
  // peak only and cannot tell its width.
  const solvers::brdf::FitSummary all = FitBlinnPhong(capture.directory.string(), stored, 2);
  ASSERT_TRUE(all.IsSolutionUsable()) << all.message;
  EXPECT_TRUE(all.lobe_identifiable);
  EXPECT_NEAR(all.params.shape, kMirrorExponent, 0.05 * kMirrorExponent);
  EXPECT_NEAR(all.params.specular[0], kMirrorKs, 0.05 * kMirrorKs);
  EXPECT_NEAR(all.params.diffuse[0], 0.4, 0.05 * 0.4);
  const solvers::brdf::FitSummary coarse = FitBlinnPhong(capture.directory.string(), stored, 0);
  EXPECT_FALSE(coarse.lobe_identifiable && std::abs(coarse.params.shape - kMirrorExponent) < 0.05 * kMirrorExponent)
      << "the coarse poses alone fitted e = " << coarse.params.shape;
}

TEST(Gonio, AStopDuringAnAdaptivePassLeavesTheLampOffAndItsFramesKept) {
  TempDir dir;
  AdaptiveCapture capture(dir);
  WatchedDome dome("lamp", capture.devices.world);
  std::atomic<bool> stop{false};
  CaptureOptions options;
  options.stop_requested = &stop;
  options.on_frame = [&stop](const config::CaptureStep& step, const FrameRecord&, int) {
    if (step.pass == 1) stop = true;  // the first frame of the first added pass
  };
  std::vector<FrameRecord> kept;
  {
    RunWriter writer(capture.directory.string(), capture.Header());
    const CaptureReport report = capture.Run(writer, dome, options);
    EXPECT_EQ(report.status, CaptureStatus::kAborted) << report.reason;
    writer.Finish(report.ToStopRecord());
    kept = writer.manifest().frames;
  }
  ASSERT_EQ(kept.size(), 4u + 1u + 18u + 1u);
  EXPECT_EQ(kept.back().pass, 1);
  EXPECT_EQ(LoadRunManifest(capture.directory.string()).frames.back().pass, 1);
  // Lamp closed dark, every axis stopped and closed.
  EXPECT_EQ(dome.state(), drivers::LightController::State::kClosed);
  ASSERT_FALSE(dome.levels_at_close.empty());
  for (const auto& levels : dome.levels_at_close) EXPECT_EQ(levels, std::vector<double>{0.0});
  for (const auto& axis : capture.arms.motion.axes) {
    EXPECT_EQ(axis->state(), drivers::Motion::State::kClosed) << axis->id();
    EXPECT_GE(static_cast<sim::SimRotaryAxis&>(*axis).stops(), 2) << axis->id();
  }

  // Resumed, the run plans the same passes from the same frames and takes only what it lacks.
  RecoveryReport recovery;
  const auto reopened = RunWriter::Reopen(capture.directory.string(), &recovery);
  EXPECT_EQ(recovery.frames_kept, static_cast<int>(kept.size()));
  const CaptureReport resumed = capture.Run(*reopened, dome);
  ASSERT_EQ(resumed.status, CaptureStatus::kComplete) << resumed.reason;
  EXPECT_EQ(resumed.frames_resumed, static_cast<int>(kept.size()));
  EXPECT_EQ(resumed.steps_total, 4 + 1 + 2 * (9 + 8));
  EXPECT_EQ(resumed.frames_written, resumed.steps_total - static_cast<int>(kept.size()));
  const std::vector<FrameRecord>& all = reopened->manifest().frames;
  for (std::size_t k = 0; k < kept.size(); ++k) EXPECT_EQ(all[k].file, kept[k].file);
  EXPECT_EQ(PosesByPass(reopened->manifest()).at(2).size(), 4u);
  EXPECT_GE(capture.arms.closest, 15.0 - capture.rig.motion->settle.tolerance_deg);
}

TEST(Gonio, AnAdaptivePlanBeforeItsDarksOrTargetIsRefusedAtItsLine) {
  struct Case {
    std::string recipe;
    int line, column;
    const char* fragment;
  };
  const std::string dark = "    - dark: {count: 2, exposures_us: [100, 4000]}\n";
  const std::string target = "    - reference_target: {count: 1, exposures_us: [4000]}\n";
  const Case cases[] = {
      // The target after the plan: the passes could not be calibrated.
      {AdaptiveRecipe("{passes: 2}", dark, target), 14, 21, "no reference_target step before the adaptive plan"},
      // The darks after it, or not at one of its exposures.
      {AdaptiveRecipe("{passes: 2}", target, dark), 14, 21, "no dark frames at"},
      {AdaptiveRecipe("{passes: 2}", "    - dark: {count: 2, exposures_us: [4000]}\n" + target), 15, 21,
       "no dark frames at 100 us"},
      {AdaptiveRecipe("{passes: 2}", "    - dark: {count: 1, exposures_us: [100, 4000]}\n" + target), 15, 21,
       "fewer than two dark frames"},
      {AdaptiveRecipe("{passes: 0}"), 15, 30, "must be within [1, 100]"},
      {AdaptiveRecipe("{added: 3}"), 15, 22, "added"},
      {AdaptiveRecipe("{min_interval_deg: 0}"), 15, 40, "must lie in [0.001, 90]"},
      {Replace(AdaptiveRecipe(), "        exposures_us: [100, 4000]\n", "        exposures_us: [100, 4000]\n        repeat: 2\n"),
       12, 17, "an adaptive plan cannot repeat"},
      {AdaptiveRecipe("{passes: 2}", kDarksAndTarget,
                      "    - poses:\n        plan: {theta_h_deg: 0, theta_d_deg: 30, adaptive: {passes: 1}}\n"),
       17, 59, "at most one adaptive plan (the first is at line 15)"},
  };
  for (const Case& c : cases) {
    TempDir dir;
    const config::RigConfig rig = config::LoadRigConfig(dir.Write("rig.yaml", NoisyGonioRigWithTarget()));
    const std::string path = dir.Write("r.yaml", c.recipe);
    photorig::testing::ExpectConfigErrorAt([&] { config::LoadRecipe(path, rig); }, path, c.line, c.column, c.fragment);
  }
}

// Dry-run states the coarse plan and the most the passes can add, and the
// shipped adaptive recipe plans clean.
TEST(Gonio, DryRunBoundsWhatTheAdaptivePassesAdd) {
  TempDir dir;
  const config::RigConfig rig = config::LoadRigConfig(dir.Write("rig.yaml", NoisyGonioRigWithTarget()));
  const config::Recipe recipe = config::LoadRecipe(dir.Write("r.yaml", AdaptiveRecipe("{passes: 3, added_poses: 5}")), rig);
  const auto steps = config::CompileSteps(recipe, rig);
  ASSERT_EQ(steps.size(), 4u + 1u + 18u);
  EXPECT_TRUE(steps.back().ends_pass);
  EXPECT_EQ(std::count_if(steps.begin(), steps.end(), [](const config::CaptureStep& s) { return s.ends_pass; }), 1);
  PlanOptions options;
  options.step_overhead_ms = 0.0;
  const RunPlan plan = PlanRun(recipe, rig, steps, options);
  ASSERT_TRUE(plan.ok()) << plan.errors.front();
  ASSERT_TRUE(plan.adaptive.has_value());
  EXPECT_EQ(plan.adaptive->coarse_poses, 9);
  EXPECT_EQ(plan.adaptive->passes, 3);
  EXPECT_EQ(plan.adaptive->added_poses, 5);
  EXPECT_EQ(plan.adaptive->max_frames, 3 * 5 * 2);
  // Per added pose: both exposures, and at most a sweep of each arm across the coarse plan's range.
  double light_lo = 1e9, light_hi = -1e9, camera_lo = 1e9, camera_hi = -1e9;
  for (const config::GonioPose& p : recipe.groups[2].poses) {
    light_lo = std::min(light_lo, p.light_arm_deg), light_hi = std::max(light_hi, p.light_arm_deg);
    camera_lo = std::min(camera_lo, p.camera_arm_deg), camera_hi = std::max(camera_hi, p.camera_arm_deg);
  }
  auto move = [](double deg) { return deg / 30.0 + 30.0 / 120.0 + 0.005; };  // trapezoid plus settle (rig above)
  EXPECT_NEAR(plan.adaptive->max_duration_s,
              15 * (0.0041 + move(light_hi - light_lo) + move(camera_hi - camera_lo)), 1e-9);
  EXPECT_EQ(plan.ToJson(steps)["adaptive"]["max_added_frames"], 30);

  const std::string shipped = SourceDir() + "/config/recipes/brdf-gonio-adaptive.yaml";
  const config::RigConfig sim_gonio = config::LoadRigConfig(config::RecipeRigPath(shipped, ""));
  const config::Recipe adaptive = config::LoadRecipe(shipped, sim_gonio);
  const RunPlan shipped_plan = PlanRun(adaptive, sim_gonio, config::CompileSteps(adaptive, sim_gonio));
  EXPECT_TRUE(shipped_plan.ok()) << shipped_plan.errors.front();
  ASSERT_TRUE(shipped_plan.adaptive.has_value());
  EXPECT_EQ(shipped_plan.adaptive->passes, 2);
}

// The shipped BRDF recipe ends with the brdf solve stage; its settings are
// checked when the recipe loads, a bad one named at its line and column.
TEST(Gonio, TheBrdfSolveStageIsParsedAndCheckedAtLoad) {
  const std::string shipped = SourceDir() + "/config/recipes/brdf-gonio.yaml";
  const config::RigConfig rig = config::LoadRigConfig(config::RecipeRigPath(shipped, ""));
  const config::Recipe recipe = config::LoadRecipe(shipped, rig);
  ASSERT_TRUE(recipe.brdf.has_value());
  EXPECT_EQ(recipe.brdf->loss, solvers::brdf::FitLoss::kWeighted);
  EXPECT_TRUE(recipe.brdf->calibrate_with_target);

  const std::string text = ReadText(shipped);
  const std::string stage = "  - brdf: {loss: weighted, calibration: reference}";
  const std::size_t at = text.find(stage);
  ASSERT_NE(at, std::string::npos);
  const int line = static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(at), '\n')) + 1;
  struct Case {
    std::string stage;
    int column;
    const char* fragment;
  };
  const Case cases[] = {
      {"  - brdf: {loss: log, calibration: camera}", 0, ""},
      {"  - brdf: {loss: squared}", 18, "'squared' is no loss (expected weighted or log)"},
      {"  - brdf: {calibration: lamp}", 25, "'lamp' is no calibration"},
      {"  - brdf: {folds: 5}", 12, "folds"},
  };
  for (const Case& c : cases) {
    TempDir dir;
    std::string edited = text;
    edited.replace(at, stage.size(), c.stage);
    // The recipe's relative rig path resolves from its own folder.
    const std::string path = dir.Write("brdf.yaml", Replace(edited, "rig: ../rigs/sim-gonio.yaml",
                                                             "rig: " + SourceDir() + "/config/rigs/sim-gonio.yaml"));
    if (c.column == 0) {
      const config::Recipe loaded = config::LoadRecipe(path, rig);
      ASSERT_TRUE(loaded.brdf.has_value());
      EXPECT_EQ(loaded.brdf->loss, solvers::brdf::FitLoss::kLog);
      EXPECT_FALSE(loaded.brdf->calibrate_with_target);
      continue;
    }
    photorig::testing::ExpectConfigErrorAt([&] { config::LoadRecipe(path, rig); }, path, line, c.column, c.fragment);
  }
}

}  // namespace
}  // namespace photorig::daemon
