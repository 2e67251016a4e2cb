// One run per injected fault kind (sim.faults): the run either completes with
// every frame intact or fails cleanly after its retry bound, the stop record
// says which, and the dome is dark afterwards either way.

#include "photorig/daemon/capture/sequencer.h"
#include "photorig/sim/devices.h"
#include "capture_fixtures.h"
#include "test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <ostream>

namespace photorig::daemon {
namespace {

using photorig::testing::TempDir;

constexpr int kLeds = 4;

struct FaultCase {
  const char* name;
  sim::CameraFaults camera;
  sim::LightFaults lights;
  bool completes;
  int min_retries;
  int dropped_frames;
};

// Remembers the levels the dome emitted when it was closed.
using photorig::testing::WatchedDome;

sim::CameraFaults CameraFault(std::set<std::uint64_t> sim::CameraFaults::*kind, std::set<std::uint64_t> at) {
  sim::CameraFaults faults;
  faults.*kind = std::move(at);
  return faults;
}

template <typename T>
sim::LightFaults LightFault(std::set<T> sim::LightFaults::*kind, std::set<T> at) {
  sim::LightFaults faults;
  faults.*kind = std::move(at);
  return faults;
}

// What a failing case prints: its name and what it expects, not the bytes of the faults.
void PrintTo(const FaultCase& c, std::ostream* out) {
  *out << c.name << " (" << (c.completes ? "completes" : "fails") << ", retries >= " << c.min_retries
       << ", dropped frames " << c.dropped_frames << ")";
}

class FaultInjection : public ::testing::TestWithParam<FaultCase> {};

TEST_P(FaultInjection, RunCompletesIntactOrFailsCleanlyWithTheLightsOff) {
  const FaultCase& c = GetParam();
  TempDir dir;
  sim::WorldConfig config;
  config.camera = {16, 12, 1.0};
  for (int i = 0; i < kLeds; ++i) config.lights.push_back({Eigen::Vector3d(0.2 * i, 0, 1).normalized(), 1.0});
  config.camera_faults = c.camera;
  config.light_faults = c.lights;
  auto world = std::make_shared<sim::World>(config);
  WatchedDome dome("dome", world);
  sim::SimCamera camera("cam", world);

  const std::vector<config::CaptureStep> steps = photorig::testing::DarkThenEachLight(kLeds);
  config::CameraConfig camera_config;
  camera_config.width = 16;
  camera_config.height = 12;
  RunManifest header;
  header.width = camera_config.width;
  header.height = camera_config.height;
  header.bit_depth = camera_config.bit_depth;
  header.lights.resize(kLeds);  // the LEDs the frames name
  RunWriter writer((dir.path() / "run").string(), header);
  CaptureOptions options;
  options.frame_timeout_margin_ms = 5;
  options.retry.initial_backoff_ms = 1;
  options.retry.max_backoff_ms = 4;
  std::vector<RunState> states;
  options.on_state = [&states](RunState state, const std::string&) { states.push_back(state); };

  const CaptureReport report = RunCapture(steps, camera_config, dome, camera, writer, options);
  writer.Finish(report.ToStopRecord());

  EXPECT_EQ(report.status, c.completes ? CaptureStatus::kComplete : CaptureStatus::kFailed) << report.reason;
  EXPECT_GE(report.retries, c.min_retries);
  EXPECT_EQ(report.dropped_frames, c.dropped_frames);
  const RunManifest manifest = LoadRunManifest(writer.directory());
  ASSERT_TRUE(manifest.stop.has_value());
  EXPECT_EQ(manifest.stop->status, report.status);
  EXPECT_EQ(manifest.stop->retries, report.retries);
  EXPECT_EQ(manifest.stop->dropped_frames, report.dropped_frames);
  EXPECT_EQ(manifest.stop->frames, static_cast<int>(manifest.frames.size()));
  const auto problems = VerifyRun(writer.directory());
  EXPECT_TRUE(problems.empty()) << problems.front();
  if (c.completes) {
    EXPECT_EQ(manifest.frames.size(), steps.size());
  } else {
    EXPECT_FALSE(report.reason.empty());
  }
  if (c.min_retries > 0) {
    EXPECT_NE(std::find(states.begin(), states.end(), RunState::kSuspended), states.end());
  }
  // Dark at every close (after each fault and at the end) and now.
  ASSERT_FALSE(dome.levels_at_close.empty());
  for (const auto& levels : dome.levels_at_close) EXPECT_EQ(levels, std::vector<double>(kLeds, 0.0));
  EXPECT_EQ(world->levels(), std::vector<double>(kLeds, 0.0));
  EXPECT_EQ(dome.state(), drivers::LightController::State::kClosed);
  EXPECT_EQ(camera.state(), drivers::Camera::State::kClosed);
}

INSTANTIATE_TEST_SUITE_P(
    EachFaultKind, FaultInjection,
    ::testing::Values(FaultCase{"none", {}, {}, true, 0, 0},
                      FaultCase{"dropped_frame", CameraFault(&sim::CameraFaults::drop_frames, {2}), {}, true, 1, 1},
                      FaultCase{"short_frames", CameraFault(&sim::CameraFaults::short_frames, {1, 3}), {}, true, 2, 2},
                      FaultCase{"corrupt_frame", CameraFault(&sim::CameraFaults::corrupt_frames, {0}), {}, true, 1, 1},
                      FaultCase{"disconnect", CameraFault(&sim::CameraFaults::disconnect_at, {2}), {}, true, 1, 0},
                      FaultCase{"light_command_timeouts", {}, LightFault<std::uint64_t>(&sim::LightFaults::fail_commands, {2, 5}), true, 1, 0},
                      FaultCase{"stuck_off_led", {}, LightFault<int>(&sim::LightFaults::stuck_off_channels, {2}), false, 0, 0},
                      FaultCase{"persistent_drops", CameraFault(&sim::CameraFaults::drop_frames, {1, 2, 3, 4, 5, 6, 7}), {}, false, 3, 4}),
    [](const ::testing::TestParamInfo<FaultCase>& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace photorig::daemon
