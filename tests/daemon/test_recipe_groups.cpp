// Capture groups beyond dark + each_led: flats, named patterns, HDR brackets,
// repeats. Validation positions, the compiled step list, the plan, and a real
// capture on the simulated dome whose frames and labels are checked on disk.

#include "photorig/daemon/capture/plan.h"
#include "photorig/daemon/pipelines/ps_pipeline.h"
#include "photorig/config/recipe.h"
#include "photorig/config/solve_requests.h"
#include "photorig/daemon/service/run.h"
#include "photorig/daemon/capture/run_store.h"
#include "config_error_check.h"
#include "test_support.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <filesystem>

namespace photorig::daemon {
namespace {

using photorig::testing::SmallRigYaml;
using photorig::testing::TempDir;

std::string RecipeWithSteps(const std::string& steps) {
  return "recipe: {name: groups, rig: rig.yaml}\ncapture:\n  exposure_us: 1000\n  steps:\n" + steps;
}

const char* kMixedSteps =
    "    - dark: {count: 2}\n"
    "    - flat: {count: 2, level: 0.5}\n"
    "    - pattern: {name: diagonal, leds: [{id: 0, level: 1.0}, 3], level: 0.25, repeat: 2}\n"
    "    - each_led: {leds: all, exposures_us: [500, 2000], repeat: 2}\n";

// The message names file:line:column of the offending value.
void ExpectRecipeError(const std::string& steps, int line, int column, const std::string& fragment) {
  TempDir dir;
  const config::RigConfig rig = config::LoadRigConfig(dir.Write("rig.yaml", SmallRigYaml()));
  const std::string path = dir.Write("r.yaml", RecipeWithSteps(steps));
  SCOPED_TRACE(steps);
  photorig::testing::ExpectConfigErrorAt([&] { config::CompileSteps(config::LoadRecipe(path, rig), rig); }, path, line, column,
                                         fragment);
}

TEST(RecipeGroups, ErrorsNameTheOffendingValue) {
  // Steps start on line 5; columns point at the offending value (or the step for rig-dependent errors).
  ExpectRecipeError("    - flat: {level: 1.5}\n", 5, 21, "must be within (0, 1]");
  ExpectRecipeError("    - flat: {count: 0}\n", 5, 21, "must be within [1, 1000]");
  ExpectRecipeError("    - flat: {leds: [0, 9]}\n", 5, 7, "LED id 9 is not in rig");
  ExpectRecipeError("    - pattern: {name: Ring, leds: [0]}\n", 5, 23, "lower-case");
  ExpectRecipeError("    - pattern: {name: ring, leds: []}\n", 5, 35, "at least one LED");
  ExpectRecipeError("    - pattern: {name: ring, leds: [0, {id: 0, level: 0.5}]}\n", 5, 39, "listed twice");
  ExpectRecipeError("    - pattern: {name: ring, leds: [{id: 1, level: 2}]}\n", 5, 51, "must be within (0, 1]");
  ExpectRecipeError("    - pattern: {name: ring, leds: [{id: 1, lvl: 1}]}\n", 5, 44, "lvl");
  ExpectRecipeError("    - each_led: {exposures_us: [1000, -5]}\n", 5, 39, "must lie in [1, 1e+08]");
  ExpectRecipeError("    - each_led: {exposures_us: [1000, 1000]}\n", 5, 39, "listed twice");
  ExpectRecipeError("    - each_led: {exposures_us: []}\n", 5, 32, "at least one exposure");
  ExpectRecipeError("    - dark: {count: 1, repeat: 0}\n", 5, 32, "must be within [1, 1000]");
  ExpectRecipeError("    - strobe: {count: 1}\n", 5, 7, "expected dark, flat, each_led, pattern, poses or reference_target");
  ExpectRecipeError("    - poses: {list: [{light_arm_deg: 10, camera_arm_deg: -20}]}\n", 5, 7,
                    "poses need a rig with a motion: section");
}

TEST(RecipeGroups, CompileToLabelledStepsWithKindsPatternsAndExposures) {
  TempDir dir;
  const config::RigConfig rig = config::LoadRigConfig(dir.Write("rig.yaml", SmallRigYaml()));
  const config::Recipe recipe = config::LoadRecipe(dir.Write("r.yaml", RecipeWithSteps(kMixedSteps)), rig);
  const auto steps = config::CompileSteps(recipe, rig);
  std::vector<std::string> labels = {"0000_dark", "0001_dark", "0002_flat", "0003_flat", "0004_pat_diagonal",
                                     "0005_pat_diagonal"};
  for (int repeat = 0; repeat < 2; ++repeat)
    for (int led = 0; led < 4; ++led)
      for (const char* exposure : {"500", "2000"}) {
        char label[32];
        std::snprintf(label, sizeof(label), "%04zu_led%02d_e%s", labels.size(), led, exposure);
        labels.push_back(label);
      }
  ASSERT_EQ(steps.size(), labels.size());
  for (std::size_t i = 0; i < steps.size(); ++i) {
    EXPECT_EQ(steps[i].label, labels[i]);
    EXPECT_EQ(steps[i].index, static_cast<int>(i));
  }
  EXPECT_EQ(steps[2].kind, config::CaptureStep::Kind::kFlat);
  EXPECT_EQ(steps[2].pattern->levels, (std::vector<double>{0.5, 0.5, 0.5, 0.5}));
  EXPECT_EQ(steps[2].led, -1);
  EXPECT_EQ(steps[4].kind, config::CaptureStep::Kind::kPattern);
  EXPECT_EQ(steps[4].group, "pattern:diagonal");
  EXPECT_EQ(steps[4].pattern->levels, (std::vector<double>{1.0, 0.0, 0.0, 0.25}));
  EXPECT_EQ(steps[4].repeat, 0);
  EXPECT_EQ(steps[5].repeat, 1);
  EXPECT_EQ(steps[9].kind, config::CaptureStep::Kind::kLight);
  EXPECT_EQ(steps[9].led, 1);
  EXPECT_EQ(steps[9].exposure_us, 2000.0);
  EXPECT_EQ(steps[0].exposure_us, 1000.0);
  EXPECT_EQ(steps[13].repeat, 0);
  EXPECT_EQ(steps[14].repeat, 1);

  // The plan counts every LED of a flat or pattern as lit, at the step's own exposure.
  PlanOptions options;
  options.step_overhead_ms = 0.0;
  const RunPlan plan = PlanRun(recipe, rig, steps, options);
  ASSERT_TRUE(plan.ok());
  const double total_ms = 2 * 1 + 2 * 1 + 2 * 1 + 4 * 2 * (0.5 + 2.0);
  EXPECT_NEAR(plan.estimate.duration_s, total_ms / 1000.0, 1e-12);
  // LED 0 and 3: flats (2 ms) + patterns (2 ms) + brackets (5 ms); LED 1 and 2: no patterns.
  EXPECT_NEAR(plan.max_led_duty, 9.0 / total_ms, 1e-12);
  EXPECT_EQ(plan.ToJson(steps)["steps"][4]["kind"], "pattern");
  options.max_led_duty = 0.3;
  EXPECT_FALSE(PlanRun(recipe, rig, steps, options).ok());
}

// kMixedSteps captured on the noise-free small rig into dir/run, unsolved.
RunRequest CaptureMixedSteps(const TempDir& dir) {
  dir.Write("rig.yaml", SmallRigYaml() + "  sensor: {read_noise_e: 0, shot_noise: false}\n");
  RunRequest request;
  request.recipe_path = dir.Write("r.yaml", RecipeWithSteps(kMixedSteps));
  request.output_directory = (dir.path() / "run").string();
  request.solve = false;
  const RunOutcome outcome = ExecuteRun(request);
  EXPECT_EQ(outcome.capture.status, CaptureStatus::kComplete) << outcome.capture.reason;
  return request;
}

TEST(RecipeGroups, CaptureWritesEveryFrameAndPhotometricStereoUsesOnlySingleLedFrames) {
  TempDir dir;
  const RunRequest request = CaptureMixedSteps(dir);
  ASSERT_FALSE(::testing::Test::HasFailure());

  const RunManifest manifest = LoadRunManifest(request.output_directory);
  ASSERT_EQ(manifest.frames.size(), 22u);
  EXPECT_EQ(manifest.frames[4].file, "frames/0004_pat_diagonal.png");
  EXPECT_EQ(manifest.frames[21].file, "frames/0021_led03_e2000.png");
  for (const FrameRecord& record : manifest.frames)
    EXPECT_TRUE(std::filesystem::exists(dir.path() / "run" / record.file)) << record.file;
  EXPECT_EQ(manifest.frames[9].exposure_us, 2000.0);
  EXPECT_EQ(manifest.frames[9].led, 1);

  auto signal = [&](int index) {  // DN above black
    cv::Mat f, dark;
    LoadFrame(request.output_directory, manifest.frames[index]).convertTo(f, CV_64F);
    LoadFrame(request.output_directory, manifest.frames[0]).convertTo(dark, CV_64F);
    return cv::Mat(f - dark);
  };
  // The rig is noise-free and linear: a 4x longer exposure collects 4x the
  // signal, a repeat reproduces the frame, and flats and patterns are the
  // level-weighted sums of the single-LED frames (each e500 frame is half of 1 ms).
  const double short_signal = cv::sum(signal(8))[0];
  ASSERT_GT(short_signal, 1000.0);
  EXPECT_NEAR(cv::sum(signal(9))[0] / short_signal, 4.0, 0.02);
  EXPECT_EQ(cv::norm(signal(8), signal(16), cv::NORM_INF), 0.0);
  const cv::Mat flat_sum = signal(6) + signal(8) + signal(10) + signal(12);  // 0.5 level x 2 x half exposure
  EXPECT_NEAR(cv::sum(signal(2))[0] / cv::sum(flat_sum)[0], 1.0, 0.01);
  const cv::Mat pattern_sum = 2.0 * signal(6) + 0.5 * signal(12);
  EXPECT_NEAR(cv::sum(signal(4))[0] / cv::sum(pattern_sum)[0], 1.0, 0.01);

  // Photometric stereo reads the 16 single-LED frames and the 2 darks, nothing else.
  const PhotometricStereoInput input = LoadRunStack(request.output_directory);
  EXPECT_EQ(input.stack.images.size(), 16u);
  EXPECT_EQ(input.dark_frames, 2);
  EXPECT_NEAR(input.stack.light_scales[1] / input.stack.light_scales[0], 4.0, 1e-9);
}

// The stack's frames are loaded on all cores: each is still its own frame's
// samples in the manifest's order, and of two damaged frames the error names
// the one the manifest lists first.
TEST(RecipeGroups, AStackIsItsFramesInOrderAndTheFirstDamagedFrameIsNamed) {
  TempDir dir;
  const RunRequest request = CaptureMixedSteps(dir);
  ASSERT_FALSE(::testing::Test::HasFailure());
  const RunManifest manifest = LoadRunManifest(request.output_directory);
  const PhotometricStereoInput input = LoadRunStack(request.output_directory);
  std::vector<const FrameRecord*> lit;
  for (const FrameRecord& record : manifest.frames)
    if (record.kind == config::CaptureStep::Kind::kLight && record.led >= 0) lit.push_back(&record);
  ASSERT_EQ(input.stack.images.size(), lit.size());
  for (std::size_t k = 0; k < lit.size(); ++k) {
    cv::Mat raw;
    LoadFrame(request.output_directory, *lit[k]).convertTo(raw, CV_32F);
    EXPECT_EQ(cv::norm(input.stack.images[k], raw, cv::NORM_INF), 0.0) << lit[k]->file;
    EXPECT_EQ(input.image_leds[k], lit[k]->led) << lit[k]->file;
  }
  // Damage the 3rd and the 12th single-LED frames: other pixels, same size.
  for (const std::size_t k : {11u, 2u}) {
    cv::Mat frame = LoadFrame(request.output_directory, *lit[k]);
    frame += cv::Scalar::all(7);
    ASSERT_TRUE(cv::imwrite((std::filesystem::path(request.output_directory) / lit[k]->file).string(), frame));
  }
  try {
    LoadRunStack(request.output_directory);
    ADD_FAILURE() << "a damaged frame loaded";
  } catch (const std::runtime_error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(lit[2]->file), std::string::npos) << message;
    EXPECT_NE(message.find("checksum"), std::string::npos) << message;
  }
}

// The rig's LED limits hold at dry-run: a plan the safety layer would cut
// mid-run (the simulated dome takes the default 10 s on-time and 50 % duty
// per 10 s window) is refused before it starts, naming the LED and the limit.
TEST(RecipeGroups, PlansBeyondTheRigsLedLimitsAreRefused) {
  TempDir dir;
  const config::RigConfig rig = config::LoadRigConfig(dir.Write("rig.yaml", SmallRigYaml()));
  const auto plan_of = [&](const std::string& exposure_us, const std::string& steps) {
    const std::string path = dir.Write("r.yaml", "recipe: {name: hot, rig: rig.yaml}\ncapture:\n  exposure_us: " +
                                                     exposure_us + "\n  steps:\n" + steps);
    const config::Recipe recipe = config::LoadRecipe(path, rig);
    return PlanRun(recipe, rig, config::CompileSteps(recipe, rig));
  };
  const RunPlan usual = plan_of("1000", "    - dark: {count: 1}\n    - each_led: {leds: all}\n");
  EXPECT_TRUE(usual.ok()) << usual.errors.front();
  // Twenty 1 s flats in a row: every LED lit nearly all of every window.
  const RunPlan hot = plan_of("1000000", "    - flat: {count: 20, level: 1.0}\n");
  ASSERT_FALSE(hot.ok());
  EXPECT_NE(hot.errors.front().find("above the rig's max_duty of 50"), std::string::npos) << hot.errors.front();
  // One 12 s exposure: beyond the 10 s on-time limit.
  const RunPlan long_on = plan_of("12000000", "    - flat: {count: 1, level: 1.0}\n");
  ASSERT_FALSE(long_on.ok());
  EXPECT_NE(long_on.errors.front().find("above the rig's max_on_ms of 10000"), std::string::npos)
      << long_on.errors.front();
}

}  // namespace
}  // namespace photorig::daemon
