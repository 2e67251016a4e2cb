#include "photorig/daemon/sequencer.h"
#include "photorig/sim/devices.h"
#include "capture_fixtures.h"
#include "test_support.h"

#include <gtest/gtest.h>

#include <filesystem>

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

RunManifest Header() {
  RunManifest header;
  header.width = 16;
  header.height = 12;
  return header;
}

CameraConfig Camera() {
  CameraConfig camera;
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
  EXPECT_EQ(report.status, "failed");
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

TEST(Sequencer, StopRequestAbortsBetweenStepsWithTheLightsOff) {
  TempDir dir;
  auto world = World(5);
  WatchedDome dome("dome", world);
  sim::SimCamera camera("cam", world);
  RunWriter writer((dir.path() / "run").string(), Header());
  std::atomic<bool> stop{false};
  CaptureOptions options;
  options.stop_requested = &stop;
  options.on_frame = [&](const CaptureStep& step, const FrameRecord&, int) {
    if (step.index == 2) stop = true;
  };
  const CaptureReport report = RunCapture(DarkThenEachLight(5), Camera(), dome, camera, writer, options);
  EXPECT_EQ(report.status, "aborted");
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
  EXPECT_EQ(report.status, "complete");
  ASSERT_EQ(writer.manifest().frames.size(), 4u);
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(writer.manifest().frames[i].index, i);
    EXPECT_EQ(writer.manifest().frames[i].frame_id, static_cast<std::uint64_t>(i));
  }
}

}  // namespace
}  // namespace photorig::daemon
