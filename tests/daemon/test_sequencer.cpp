#include "photorig/daemon/capture/sequencer.h"
#include "photorig/drivers/light_safety.h"
#include "photorig/sim/devices.h"
#include "capture_fixtures.h"
#include "test_support.h"

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <thread>

namespace photorig::daemon {
namespace {

using photorig::testing::TempDir;

std::shared_ptr<sim::World> World(int lights) {
  sim::WorldConfig config;
  config.camera = {16, 12, 1.0};
  for (int i = 0; i < lights; ++i) config.lights.push_back({Eigen::Vector3d(0.1 * i, 0, 1).normalized(), 1.0});
  return std::make_shared<sim::World>(config);
}

// A simulated camera whose link dies after `good_frames` frames.
class FailingCamera : public sim::SimCamera {
 public:
  FailingCamera(std::shared_ptr<sim::World> world, int good_frames)
      : SimCamera("flaky-cam", std::move(world)), good_frames_(good_frames) {}

 protected:
  Result<drivers::Frame> DoWaitFrame(int timeout_ms) override {
    if (delivered_++ >= good_frames_)
      return Status{StatusCode::kUnavailable, "camera flaky-cam: link lost"};
    return SimCamera::DoWaitFrame(timeout_ms);
  }

 private:
  int good_frames_;
  int delivered_ = 0;
};

using photorig::testing::DarkThenEachLight;
using photorig::testing::WatchedDome;

// A simulated camera whose frames take `exposure_ms` of wall-clock time to
// arrive, as a real long exposure does (the simulated one renders at once).
class SlowCamera : public sim::SimCamera {
 public:
  SlowCamera(std::shared_ptr<sim::World> world, int exposure_ms)
      : SimCamera("slow-cam", std::move(world)), exposure_ms_(exposure_ms) {}

 protected:
  Result<drivers::Frame> DoWaitFrame(int timeout_ms) override {
    using Clock = std::chrono::steady_clock;
    if (!waiting_) waiting_since_ = Clock::now();
    waiting_ = true;
    const auto due = waiting_since_ + std::chrono::milliseconds(exposure_ms_);
    std::this_thread::sleep_until(std::min(due, Clock::now() + std::chrono::milliseconds(timeout_ms)));
    if (Clock::now() < due) return Status{StatusCode::kTimeout, "camera slow-cam: exposure still running"};
    waiting_ = false;
    return SimCamera::DoWaitFrame(timeout_ms);
  }

 private:
  int exposure_ms_;
  bool waiting_ = false;
  std::chrono::steady_clock::time_point waiting_since_;
};

RunManifest Header() {
  RunManifest header;
  header.width = 16;
  header.height = 12;
  return header;
}

config::CameraConfig Camera() {
  config::CameraConfig camera;
  camera.width = 16;
  camera.height = 12;
  return camera;
}

TEST(Sequencer, DeviceFaultFailsTheRunKeepsFramesAndLeavesTheLightsOff) {
  TempDir dir;
  auto world = World(4);
  WatchedDome dome("dome", world);
  FailingCamera camera(world, 3);
  RunWriter writer((dir.path() / "run").string(), Header());
  const CaptureReport report = RunCapture(DarkThenEachLight(4), Camera(), dome, camera, writer, {});
  EXPECT_EQ(report.status, CaptureStatus::kFailed);
  EXPECT_NE(report.reason.find("flaky-cam: link lost"), std::string::npos) << report.reason;
  EXPECT_EQ(report.frames_written, 3);
  EXPECT_EQ(writer.manifest().frames.size(), 3u);
  for (const auto& frame : writer.manifest().frames)
    EXPECT_TRUE(std::filesystem::exists(dir.path() / "run" / frame.file));
  EXPECT_EQ(dome.state(), drivers::LightController::State::kClosed);
  EXPECT_EQ(camera.state(), drivers::Camera::State::kClosed);
  ASSERT_FALSE(dome.levels_at_close.empty());
  for (const auto& levels : dome.levels_at_close) EXPECT_EQ(levels, std::vector<double>(4, 0.0));
}

// An exposure longer than the safety layer's watchdog: the sequencer's
// keep-alives while it waits hold the LED on; without them the watchdog
// takes the sequencer for stalled and cuts the light mid-exposure.
TEST(Sequencer, AnExposureLongerThanTheLightWatchdogIsNotCut) {
  for (const bool keep_alive : {true, false}) {
    SCOPED_TRACE(keep_alive ? "with keep-alives" : "without");
    TempDir dir;
    auto world = World(2);
    drivers::LightSafetyOptions safety;
    safety.watchdog_ms = 300;
    drivers::SafeLightController lights(std::make_unique<WatchedDome>("dome", world), safety);
    SlowCamera camera(world, 700);
    RunWriter writer((dir.path() / "run").string(), Header());
    CaptureOptions options;
    options.lights_keepalive_ms = keep_alive ? 100 : 5000;
    options.retry.max_attempts_per_step = 1;
    std::vector<config::CaptureStep> steps = DarkThenEachLight(2);
    steps.resize(2);  // the dark and one lit frame
    const CaptureReport report = RunCapture(steps, Camera(), lights, camera, writer, options);
    if (keep_alive) {
      EXPECT_EQ(report.status, CaptureStatus::kComplete) << report.reason;
      EXPECT_TRUE(lights.cuts().empty());
    } else {
      EXPECT_EQ(report.status, CaptureStatus::kFailed);
      ASSERT_FALSE(lights.cuts().empty());
      EXPECT_NE(lights.cuts().front().find("watchdog"), std::string::npos) << lights.cuts().front();
    }
  }
}

TEST(Sequencer, StopRequestAbortsBetweenStepsWithTheLightsOff) {
  TempDir dir;
  auto world = World(5);
  WatchedDome dome("dome", world);
  sim::SimCamera camera("cam", world);
  RunWriter writer((dir.path() / "run").string(), Header());
  std::atomic<bool> stop{false};
  CaptureOptions options;
  options.stop_requested = &stop;
  options.on_frame = [&](const config::CaptureStep& step, const FrameRecord&, int) {
    if (step.index == 2) stop = true;
  };
  const CaptureReport report = RunCapture(DarkThenEachLight(5), Camera(), dome, camera, writer, options);
  EXPECT_EQ(report.status, CaptureStatus::kAborted);
  EXPECT_EQ(report.frames_written, 3);
  ASSERT_FALSE(dome.levels_at_close.empty());
  for (const auto& levels : dome.levels_at_close) EXPECT_EQ(levels, std::vector<double>(5, 0.0));
  EXPECT_EQ(world->levels(), std::vector<double>(5, 0.0));
}

TEST(Sequencer, CompleteRunWritesEveryStepInOrder) {
  TempDir dir;
  auto world = World(3);
  sim::SimLightDome dome("dome", world);
  sim::SimCamera camera("cam", world);
  RunWriter writer((dir.path() / "run").string(), Header());
  const CaptureReport report = RunCapture(DarkThenEachLight(3), Camera(), dome, camera, writer, {});
  EXPECT_EQ(report.status, CaptureStatus::kComplete);
  ASSERT_EQ(writer.manifest().frames.size(), 4u);
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(writer.manifest().frames[i].index, i);
    EXPECT_EQ(writer.manifest().frames[i].frame_id, static_cast<std::uint64_t>(i));
  }
}

}  // namespace
}  // namespace photorig::daemon

namespace photorig::daemon {
namespace {

config::CameraConfig HardwareTriggered() {
  config::CameraConfig camera = Camera();
  camera.trigger.mode = drivers::TriggerMode::kHardware;
  return camera;
}

// Counts pulses and passes each one on to the simulated camera's input.
class CountingWire : public sim::SimTriggerLine {
 public:
  using SimTriggerLine::SimTriggerLine;
  int pulses = 0;

 protected:
  Status DoFire(std::chrono::microseconds width) override {
    ++pulses;
    return SimTriggerLine::DoFire(width);
  }
};

TEST(HardwareTrigger, OnePulsePerFrameGivesTheSameFramesAsSoftwareTriggers) {
  TempDir dir;
  auto world = World(3);
  sim::SimLightDome dome("dome", world);
  sim::SimCamera camera("cam", world);
  RunWriter software((dir.path() / "software").string(), Header());
  ASSERT_EQ(RunCapture(DarkThenEachLight(3), Camera(), dome, camera, software, {}).status, CaptureStatus::kComplete);

  CountingWire wire("wire", world);
  CaptureOptions options;
  options.trigger_output = &wire;
  RunWriter hardware((dir.path() / "hardware").string(), Header());
  sim::SimCamera armed("cam", world);  // a camera's noise follows its trigger count: start this one at 0 too
  const CaptureReport report = RunCapture(DarkThenEachLight(3), HardwareTriggered(), dome, armed, hardware, options);
  ASSERT_EQ(report.status, CaptureStatus::kComplete) << report.reason;
  EXPECT_EQ(wire.pulses, 4);
  EXPECT_EQ(wire.state(), drivers::TriggerOutput::State::kClosed);  // released at the end
  ASSERT_EQ(hardware.manifest().frames.size(), 4u);
  for (std::size_t i = 0; i < 4; ++i) {
    // Same world, same seed and trigger counts: the same noisy pixels, whichever trigger took them.
    const cv::Mat a = LoadFrame(software.directory(), software.manifest().frames[i]);
    const cv::Mat b = LoadFrame(hardware.directory(), hardware.manifest().frames[i]);
    EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0) << i;
  }
}

// The output fires but the camera never sees the pulse (a broken wire): every
// wait times out, the run fails after its retries with the lights off.
class BrokenWire : public drivers::TriggerOutput {
 public:
  BrokenWire() : TriggerOutput("broken-wire") {}
  ~BrokenWire() override { (void)Close(); }
  int pulses = 0;

 protected:
  Status DoOpen() override { return Status::Ok(); }
  Status DoFire(std::chrono::microseconds) override { ++pulses; return Status::Ok(); }
  Status DoClose() override { return Status::Ok(); }
};

TEST(HardwareTrigger, APulseThatNeverArrivesTimesOutAndFailsCleanly) {
  TempDir dir;
  auto world = World(2);
  WatchedDome dome("dome", world);
  sim::SimCamera camera("cam", world);
  BrokenWire wire;
  CaptureOptions options;
  options.trigger_output = &wire;
  options.frame_timeout_margin_ms = 5;
  options.retry.initial_backoff_ms = 1;
  options.retry.max_backoff_ms = 2;
  RunWriter writer((dir.path() / "run").string(), Header());
  const CaptureReport report = RunCapture(DarkThenEachLight(2), HardwareTriggered(), dome, camera, writer, options);
  EXPECT_EQ(report.status, CaptureStatus::kFailed);
  EXPECT_NE(report.reason.find("no frame within"), std::string::npos) << report.reason;
  EXPECT_EQ(wire.pulses, options.retry.max_attempts_per_step);
  EXPECT_EQ(report.dropped_frames, options.retry.max_attempts_per_step);
  EXPECT_EQ(wire.state(), drivers::TriggerOutput::State::kClosed);
  EXPECT_EQ(writer.manifest().frames.size(), 0u);
  ASSERT_FALSE(dome.levels_at_close.empty());
  for (const auto& levels : dome.levels_at_close) EXPECT_EQ(levels, std::vector<double>(2, 0.0));

  // A hardware-triggered camera with no output at all is refused before any frame.
  RunWriter none((dir.path() / "none").string(), Header());
  const CaptureReport refused = RunCapture(DarkThenEachLight(2), HardwareTriggered(), dome, camera, none, {});
  EXPECT_EQ(refused.status, CaptureStatus::kFailed);
  EXPECT_NE(refused.reason.find("no trigger output"), std::string::npos) << refused.reason;
}

}  // namespace
}  // namespace photorig::daemon
