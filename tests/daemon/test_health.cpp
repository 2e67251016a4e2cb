// Capture health checks (frame_health.h): a capture whose frames do not show
// what the plan asked for fails, naming the LEDs or frames and the statistic;
// a healthy capture raises no alarm; photometric stereo refuses a black stack.

#include "photorig/daemon/capture/frame_health.h"
#include "photorig/daemon/service/run.h"
#include "config_error_check.h"
#include "test_support.h"

#include <gtest/gtest.h>

#include <csignal>
#include <cstdio>
#include <filesystem>
#include <regex>
#include <string>
#include <sys/wait.h>
#include <unistd.h>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
using photorig::testing::ReadText;
using photorig::testing::RunPhotorig;
using photorig::testing::SmallRecipeYaml;
using photorig::testing::SmallRigYaml;
using photorig::testing::SourceDir;
using photorig::testing::TempDir;

// Captures `recipe` (YAML) into DIR/run with short retry back-offs, unsolved.
RunOutcome CaptureRecipe(const TempDir& dir, const std::string& recipe) {
  RunRequest request;
  request.recipe_path = dir.Write("recipe.yaml", recipe);
  request.output_directory = (dir.path() / "run").string();
  request.solve = false;
  request.retry.initial_backoff_ms = 1;
  request.retry.max_backoff_ms = 4;
  return ExecuteRun(request);
}

// Captures the small dome (4 LEDs, one dark) with `faults` injected and the
// rig's YAML extended by `rig_tail` (e.g. a health: section).
RunOutcome Capture(const TempDir& dir, const std::string& faults, const std::string& rig_tail = "",
                   double exposure_us = 1000) {
  dir.Write("rig.yaml", SmallRigYaml(faults) + rig_tail);
  const std::string recipe = std::regex_replace(SmallRecipeYaml("rig.yaml"), std::regex("exposure_us: 1000"),
                                                "exposure_us: " + std::to_string(exposure_us));
  return CaptureRecipe(dir, recipe);
}

bool Contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

std::vector<std::string> StoredFiles(const std::string& run) {
  std::vector<std::string> files;
  for (const FrameRecord& record : LoadRunManifest(run).frames) files.push_back(fs::path(record.file).filename());
  return files;
}

TEST(CaptureHealth, HealthyCaptureRaisesNoAlarm) {
  TempDir dir;
  const RunOutcome outcome = Capture(dir, "");
  EXPECT_EQ(outcome.capture.status, CaptureStatus::kComplete) << outcome.capture.reason;
  EXPECT_TRUE(outcome.capture.health.empty());
  EXPECT_EQ(outcome.capture.frames_rejected, 0);
  EXPECT_EQ(outcome.capture.retries, 0);
  EXPECT_EQ(StoredFiles(outcome.directory).size(), 5u);
}

TEST(CaptureHealth, DeadLedAmongFourIsNamedAfterItsRetriesAndTheOthersAreStored) {
  TempDir dir;
  const RunOutcome outcome = Capture(dir, "{lights: {dim_channels: {2: 0.0}}}");
  const CaptureReport& report = outcome.capture;
  ASSERT_EQ(report.status, CaptureStatus::kFailed);
  EXPECT_TRUE(Contains(report.reason, "LED 2 did not light: brightest pixel")) << report.reason;
  EXPECT_TRUE(Contains(report.reason, "sigma")) << report.reason;
  ASSERT_EQ(report.health.size(), 1u);
  EXPECT_EQ(report.health[0].check, HealthCheck::kNoLight);
  EXPECT_EQ(report.health[0].led_id, 2);
  EXPECT_LT(report.health[0].value, report.health[0].threshold);
  // Retried to the step's bound (4 attempts), then the rest was still taken.
  EXPECT_EQ(report.retries, 3);
  EXPECT_EQ(report.frames_rejected, 4);
  EXPECT_EQ(StoredFiles(outcome.directory),
            (std::vector<std::string>{"0000_dark.png", "0001_led00.png", "0002_led01.png", "0004_led03.png"}));
  const RunManifest manifest = LoadRunManifest(outcome.directory);
  ASSERT_TRUE(manifest.stop.has_value());
  EXPECT_EQ(manifest.stop->status, CaptureStatus::kFailed);
  EXPECT_EQ(manifest.stop->reason, report.reason);
}

TEST(CaptureHealth, LensCapFailsEveryLedAndNamesThemAll) {
  TempDir dir;
  const RunOutcome outcome = Capture(dir, "{camera: {lens_cap: true}}");
  ASSERT_EQ(outcome.capture.status, CaptureStatus::kFailed);
  EXPECT_TRUE(Contains(outcome.capture.reason, "LEDs 0-3 did not light")) << outcome.capture.reason;
  EXPECT_TRUE(Contains(outcome.capture.reason, "power and wiring")) << outcome.capture.reason;
  EXPECT_EQ(StoredFiles(outcome.directory), std::vector<std::string>{"0000_dark.png"});
}

TEST(CaptureHealth, StaleBufferIsCaughtAndRetried) {
  TempDir dir;
  // Trigger 2 (LED 1's frame) hands out LED 0's pixels again; the retry gets a fresh frame.
  const RunOutcome outcome = Capture(dir, "{camera: {repeat_frames: [2]}}");
  EXPECT_EQ(outcome.capture.status, CaptureStatus::kComplete) << outcome.capture.reason;
  EXPECT_EQ(outcome.capture.retries, 1);
  EXPECT_EQ(outcome.capture.frames_rejected, 1);
  EXPECT_EQ(StoredFiles(outcome.directory).size(), 5u);
}

TEST(CaptureHealth, PersistentStaleBufferFailsTheRun) {
  TempDir dir;
  const RunOutcome outcome = Capture(dir, "{camera: {repeat_frames: [2, 3, 4, 5, 6, 7, 8, 9, 10]}}");
  ASSERT_EQ(outcome.capture.status, CaptureStatus::kFailed);
  EXPECT_TRUE(Contains(outcome.capture.reason, "LEDs 1-3 repeated the previous frame pixel for pixel"))
      << outcome.capture.reason;
}

TEST(CaptureHealth, SaturatedFramesAreReported) {
  TempDir dir;
  const RunOutcome outcome = Capture(dir, "", "", 200000);
  ASSERT_EQ(outcome.capture.status, CaptureStatus::kFailed);
  EXPECT_TRUE(Contains(outcome.capture.reason, "overexposed")) << outcome.capture.reason;
  EXPECT_TRUE(Contains(outcome.capture.reason, "% of the pixels clipped (allowed 2.0%)")) << outcome.capture.reason;
  ASSERT_FALSE(outcome.capture.health.empty());
  EXPECT_EQ(outcome.capture.health[0].check, HealthCheck::kClipped);
  EXPECT_GT(outcome.capture.health[0].value, 0.02);
}

// A bracket's short exposure of a dim subject sits in the noise by design:
// only its longest exposure must show light (as only its shortest must not clip).
TEST(CaptureHealth, ABracketsShortExposureMayBeDimButItsLongestMustLight) {
  const auto capture = [](const TempDir& dir, const std::string& exposures) {
    dir.Write("rig.yaml", SmallRigYaml(""));
    return CaptureRecipe(dir, std::regex_replace(SmallRecipeYaml("rig.yaml"), std::regex("each_led: \\{leds: all\\}"),
                                                 "each_led: {leds: all, exposures_us: " + exposures + "}"));
  };
  TempDir bracketed;
  const RunOutcome ok = capture(bracketed, "[1, 1000]");
  EXPECT_EQ(ok.capture.status, CaptureStatus::kComplete) << ok.capture.reason;
  EXPECT_EQ(StoredFiles(ok.directory).size(), 9u);
  TempDir dim;
  const RunOutcome failed = capture(dim, "[1, 2]");
  ASSERT_EQ(failed.capture.status, CaptureStatus::kFailed);
  EXPECT_TRUE(Contains(failed.capture.reason, "did not light")) << failed.capture.reason;
}

TEST(CaptureHealth, DimLedIsNamedByItsNeighbours) {
  TempDir dir;
  const RunOutcome outcome = Capture(dir, "{lights: {dim_channels: {1: 0.15}}}", "", 4000);
  ASSERT_EQ(outcome.capture.status, CaptureStatus::kFailed);
  EXPECT_TRUE(Contains(outcome.capture.reason, "LED 1 dead or dim")) << outcome.capture.reason;
  EXPECT_TRUE(Contains(outcome.capture.reason, "LEDs 0, 2, 3")) << outcome.capture.reason;
  ASSERT_EQ(outcome.capture.health.size(), 1u);
  EXPECT_NEAR(outcome.capture.health[0].value, 0.15, 0.05);
  EXPECT_EQ(StoredFiles(outcome.directory).size(), 5u);  // every frame is in; the LED is the fault
}

TEST(CaptureHealth, ChecksOffLetABlackCaptureThroughAndPhotometricStereoRefusesIt) {
  TempDir dir;
  const RunOutcome outcome = Capture(dir, "{camera: {lens_cap: true}}", "health: {enabled: false}\n");
  ASSERT_EQ(outcome.capture.status, CaptureStatus::kComplete) << outcome.capture.reason;
  config::PhotometricStereoRequest request;
  request.method = solvers::ps::Method::kLambertian;
  request.integrator = std::nullopt;  // normals only
  const PhotometricStereoResult result =
      SolvePhotometricStereoRun(outcome.directory, request, (dir.path() / "ps").string());
  EXPECT_FALSE(result.usable());
  EXPECT_EQ(result.summary.termination, solvers::core::Termination::kFailure);
  EXPECT_TRUE(Contains(result.summary.message, "no usable signal: 0 of 4 images")) << result.summary.message;
}

TEST(CaptureHealth, RigHealthSectionIsReadAndRangeChecked) {
  TempDir dir;
  const config::RigConfig defaults = config::LoadRigConfig(dir.Write("default.yaml", SmallRigYaml()));
  EXPECT_TRUE(defaults.health.enabled);
  EXPECT_EQ(defaults.health.lit_sigma, 10.0);
  EXPECT_EQ(defaults.health.max_clipped_fraction, 0.02);
  // The simulated sensor's full well (15000 e at 4 e/DN) fills before its 12-bit ADC does.
  EXPECT_NEAR(defaults.health.saturation_dn, 64 + 15000.0 / 4 - 3 * 6.0 / 4, 1e-9);
  const config::RigConfig set = config::LoadRigConfig(dir.Write(
      "set.yaml", SmallRigYaml() + "health: {lit_sigma: 20, max_clipped_fraction: 0.1, min_neighbour_ratio: 0, "
                                   "neighbours: 6, max_brightness_ratio: 3}\n"));
  EXPECT_EQ(set.health.lit_sigma, 20.0);
  EXPECT_EQ(set.health.max_clipped_fraction, 0.1);
  EXPECT_EQ(set.health.min_neighbour_ratio, 0.0);
  EXPECT_EQ(set.health.neighbours, 6);
  EXPECT_EQ(set.health.max_brightness_ratio, 3.0);

  const std::string rig = SmallRigYaml();
  const int line = static_cast<int>(std::count(rig.begin(), rig.end(), '\n')) + 2;
  const std::string low = dir.Write("low.yaml", rig + "health:\n  lit_sigma: 1\n");
  photorig::testing::ExpectConfigErrorAt([&] { config::LoadRigConfig(low); }, low, line, 14, "must lie in [3, 1000]",
                                         "health.lit_sigma");
  const std::string unknown = dir.Write("unknown.yaml", rig + "health:\n  lit_sigmas: 5\n");
  photorig::testing::ExpectConfigErrorAt([&] { config::LoadRigConfig(unknown); }, unknown, line, 3, "lit_sigmas");
  const std::string channel = dir.Write("channel.yaml", SmallRigYaml("{lights: {dim_channels: {two: 0.5}}}"));
  EXPECT_THROW(config::LoadRigConfig(channel), config::ConfigError);
}

TEST(FrameHealthDescribe, GroupsLedsIntoRanges) {
  std::vector<HealthFinding> findings;
  for (int id : {0, 1, 2, 5, 7, 8}) {
    HealthFinding f;
    f.check = HealthCheck::kNoLight;
    f.led_id = id;
    f.value = 3.0 + id;
    f.threshold = 21.0;
    f.noise_sigma_dn = 2.1;
    findings.push_back(f);
  }
  const std::string text = FrameHealth::Describe(findings);
  EXPECT_TRUE(Contains(text, "LEDs 0-2, 5, 7-8 did not light: brightest pixel at most 11.0 DN above dark")) << text;
  EXPECT_TRUE(Contains(text, "(needs a pixel >= 10 sigma = 21.0 DN above dark)")) << text;
}

// A dead LED's mean response is noise around zero: it reads 0.0, not -0.0.
TEST(FrameHealthDescribe, ANoiseLevelResponseHasNoMinusSign) {
  HealthFinding f;
  f.check = HealthCheck::kNoLight;
  f.led_id = 5;
  f.value = 4.2;
  f.mean_response_dn = -0.04;
  f.threshold = 21.0;
  f.noise_sigma_dn = 2.1;
  const std::string text = FrameHealth::Describe({f});
  EXPECT_TRUE(Contains(text, "mean response 0.0 DN")) << text;
  EXPECT_FALSE(Contains(text, "-0.0")) << text;
}

// The reproduction from the issue: the lights are driven over Modbus TCP by a
// separate photorig-sim-modbus process while the camera renders its own
// in-process world, so no LED ever reaches the frames.
class SimModbusProcess {
 public:
  explicit SimModbusProcess(const std::string& rig) {
    int out[2];
    if (::pipe(out) != 0) return;
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(out[1], STDOUT_FILENO);
      ::close(out[0]);
      const std::string binary = std::string(PHOTORIG_BIN_DIR) + "/photorig-sim-modbus";
      ::execl(binary.c_str(), binary.c_str(), "--rig", rig.c_str(), "--port", "0", static_cast<char*>(nullptr));
      ::_exit(127);
    }
    ::close(out[1]);
    // "tcp 127.0.0.1:PORT" once it serves.
    FILE* stream = ::fdopen(out[0], "r");
    char line[128] = {};
    if (stream && std::fgets(line, sizeof(line), stream)) {
      std::smatch match;
      const std::string text = line;
      if (std::regex_search(text, match, std::regex(":([0-9]+)"))) port_ = std::stoi(match[1]);
    }
    if (stream) std::fclose(stream);
  }
  ~SimModbusProcess() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGTERM);
    ::waitpid(pid_, nullptr, 0);
  }
  int port() const { return port_; }

 private:
  pid_t pid_ = -1;
  int port_ = 0;
};

TEST(CaptureHealthEndToEnd, LightsOnAnotherWorldFailTheCaptureAndTheBlackStackIsNotSolved) {
  TempDir dir;
  const std::string modbus_rig = SourceDir() + "/config/rigs/sim-dome-modbus.yaml";
  SimModbusProcess server(modbus_rig);
  ASSERT_GT(server.port(), 0);
  std::string rig = ReadText(modbus_rig);
  rig = std::regex_replace(rig, std::regex("host: sim"), "host: 127.0.0.1");
  rig = std::regex_replace(rig, std::regex("port: 0 "), "port: " + std::to_string(server.port()) + " ");
  const std::string external = dir.Write("external.yaml", rig);
  const std::string recipe = SourceDir() + "/config/recipes/ps-sphere.yaml";

  const fs::path checked = dir.path() / "checked";
  EXPECT_EQ(RunPhotorig("run " + recipe + " --rig " + external + " --out " + checked.string(), dir.path() / "log"), 1);
  const std::string log = ReadText(dir.path() / "log");
  EXPECT_TRUE(Contains(log, "capture: failed")) << log;
  EXPECT_TRUE(Contains(log, "LEDs 0-47 did not light: brightest pixel")) << log;
  EXPECT_FALSE(fs::exists(checked / "results")) << "a failed capture must not be solved";

  // With the checks off the black stack is captured, and the solver refuses it.
  const std::string unchecked_rig = dir.Write("unchecked.yaml", rig + "\nhealth: {enabled: false}\n");
  const fs::path unchecked = dir.path() / "unchecked";
  EXPECT_EQ(RunPhotorig("run " + recipe + " --rig " + unchecked_rig + " --out " + unchecked.string() + " --no-solve",
                        dir.path() / "log2"),
            0)
      << ReadText(dir.path() / "log2");
  EXPECT_EQ(RunPhotorig("solve ps --run " + unchecked.string(), dir.path() / "log3"), 1);
  const std::string solve_log = ReadText(dir.path() / "log3");
  EXPECT_TRUE(Contains(solve_log, "no usable signal: 0 of 48 images")) << solve_log;
}

}  // namespace
}  // namespace photorig::daemon
