#include "photorig/sim/devices.h"

#include <gtest/gtest.h>

namespace photorig::sim {
namespace {

std::shared_ptr<World> SmallWorld() {
  WorldConfig config;
  config.scene.shape = Scene::Shape::kSphere;
  config.scene.sphere_radius_mm = 2.0;
  config.camera = {32, 24, 0.2};
  config.lights = {{Eigen::Vector3d(0, 0, 1), 1.0}, {Eigen::Vector3d(0.6, 0, 0.8), 1.0}};
  return std::make_shared<World>(config);
}

drivers::CameraSettings Settings() {
  drivers::CameraSettings settings;
  settings.exposure_us = 5000.4;
  return settings;
}

TEST(SimCamera, IllegalTransitionsReturnErrorsAndChangeNothing) {
  SimCamera camera("cam", SmallWorld());
  EXPECT_EQ(camera.Trigger().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(camera.Start().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(camera.Configure(Settings()).status().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(camera.state(), drivers::Camera::State::kClosed);
  ASSERT_TRUE(camera.Open().ok());
  EXPECT_EQ(camera.Open().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(camera.WaitFrame(10).status().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(camera.state(), drivers::Camera::State::kOpen);
}

TEST(SimCamera, ConfigureReportsWhatItAdjusted) {
  SimCamera camera("cam", SmallWorld());
  ASSERT_TRUE(camera.Open().ok());
  drivers::CameraSettings settings = Settings();
  settings.gain_db = 40.0;
  settings.bit_depth = 16;
  auto adjustments = camera.Configure(settings);
  ASSERT_TRUE(adjustments.ok());
  std::map<std::string, double> applied;
  for (const auto& a : adjustments.value()) applied[a.field] = a.applied;
  EXPECT_EQ(applied.at("exposure_us"), 5000.0);
  EXPECT_EQ(applied.at("gain_db"), 24.0);
  EXPECT_EQ(applied.at("bit_depth"), 12.0);
  EXPECT_EQ(camera.settings().exposure_us, 5000.0);
  settings.width = 100;
  EXPECT_EQ(camera.Configure(settings).status().code(), StatusCode::kInvalidArgument);
}

TEST(SimCamera, FramesShowTheLightsTheDomeSet) {
  auto world = SmallWorld();
  SimLightDome dome("dome", world);
  SimCamera camera("cam", world);
  ASSERT_TRUE(dome.Open().ok());
  ASSERT_TRUE(camera.Open().ok());
  ASSERT_TRUE(camera.Configure(Settings()).ok());
  ASSERT_TRUE(camera.Start().ok());
  EXPECT_EQ(camera.WaitFrame(50).status().code(), StatusCode::kTimeout);

  auto capture = [&](const drivers::LightPattern& pattern) {
    EXPECT_TRUE(dome.SetPattern(pattern).ok());
    EXPECT_TRUE(camera.Trigger().ok());
    auto frame = camera.WaitFrame(100);
    EXPECT_TRUE(frame.ok());
    return std::move(frame).value();
  };
  const drivers::Frame dark = capture(drivers::LightPattern::AllOff(2));
  const drivers::Frame lit = capture(drivers::LightPattern::Single(2, 0, 1.0));
  EXPECT_EQ(lit.frame_id, dark.frame_id + 1);
  EXPECT_EQ(lit.width, 32);
  EXPECT_EQ(lit.pixel_format, "Mono12");
  const std::size_t centre = 12 * 32 + 16;
  EXPECT_GT(lit.pixels[centre], dark.pixels[centre] + 100);
}

TEST(SimCamera, HardwareTriggerTakesAFramePerPulseOnlyWhileArmed) {
  auto world = SmallWorld();
  SimLightDome dome("dome", world);
  SimCamera camera("cam", world);
  SimTriggerLine trigger("wire", world);
  ASSERT_TRUE(dome.Open().ok());
  ASSERT_TRUE(camera.Open().ok());
  drivers::CameraSettings settings = Settings();
  settings.trigger = drivers::TriggerMode::kHardware;
  settings.trigger_line = "Line3";
  EXPECT_EQ(camera.Configure(settings).status().code(), StatusCode::kInvalidArgument);  // no such input
  settings.trigger_line = "Line1";
  ASSERT_TRUE(camera.Configure(settings).ok());
  EXPECT_EQ(trigger.Fire(std::chrono::microseconds(50)).code(), StatusCode::kFailedPrecondition);  // closed
  ASSERT_TRUE(trigger.Open().ok());
  // Not streaming yet: the camera is not armed, so the pulse is lost and said so.
  EXPECT_EQ(trigger.Fire(std::chrono::microseconds(50)).code(), StatusCode::kFailedPrecondition);
  ASSERT_TRUE(camera.Start().ok());
  EXPECT_EQ(camera.Trigger().code(), StatusCode::kFailedPrecondition);  // software triggers are ignored
  EXPECT_EQ(camera.WaitFrame(10).status().code(), StatusCode::kTimeout);
  ASSERT_TRUE(dome.SetPattern(drivers::LightPattern::Single(2, 1, 1.0)).ok());
  ASSERT_TRUE(trigger.Fire(std::chrono::microseconds(50)).ok());
  ASSERT_TRUE(trigger.Fire(std::chrono::microseconds(50)).ok());
  auto first = camera.WaitFrame(10), second = camera.WaitFrame(10);
  ASSERT_TRUE(first.ok() && second.ok());
  EXPECT_EQ(second.value().frame_id, first.value().frame_id + 1);
  EXPECT_EQ(camera.WaitFrame(10).status().code(), StatusCode::kTimeout);  // one frame per pulse
  ASSERT_TRUE(camera.Stop().ok());
  EXPECT_EQ(trigger.Fire(std::chrono::microseconds(50)).code(), StatusCode::kFailedPrecondition);  // disarmed
}

TEST(SimTriggerLine, IllegalTransitionsReturnErrorsAndChangeNothing) {
  SimTriggerLine trigger("wire", SmallWorld());
  EXPECT_EQ(trigger.Fire(std::chrono::microseconds(50)).code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(trigger.state(), drivers::TriggerOutput::State::kClosed);
  ASSERT_TRUE(trigger.Open().ok());
  EXPECT_EQ(trigger.Open().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(trigger.state(), drivers::TriggerOutput::State::kOpen);
  EXPECT_EQ(trigger.Fire(std::chrono::microseconds(0)).code(), StatusCode::kInvalidArgument);
  ASSERT_TRUE(trigger.Close().ok());
  ASSERT_TRUE(trigger.Close().ok());
  EXPECT_EQ(trigger.state(), drivers::TriggerOutput::State::kClosed);
}

TEST(SimLightDome, RejectsBadPatternsAndEndsDark) {
  auto world = SmallWorld();
  SimLightDome dome("dome", world);
  EXPECT_EQ(dome.SetPattern(drivers::LightPattern::AllOff(2)).code(), StatusCode::kFailedPrecondition);
  ASSERT_TRUE(dome.Open().ok());
  EXPECT_EQ(dome.SetPattern(drivers::LightPattern::AllOff(3)).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(dome.SetPattern({{0.5, 1.5}}).code(), StatusCode::kInvalidArgument);
  ASSERT_TRUE(dome.SetPattern({{0.5, 1.0}}).ok());
  EXPECT_EQ(dome.ReadBack().value().levels, (std::vector<double>{0.5, 1.0}));
  ASSERT_TRUE(dome.Close().ok());
  EXPECT_EQ(world->levels(), (std::vector<double>{0.0, 0.0}));
}

}  // namespace
}  // namespace photorig::sim

namespace photorig::sim {
namespace {

struct FaultyRig {
  std::shared_ptr<World> world;
  SimLightDome dome;
  SimCamera camera;
  explicit FaultyRig(WorldConfig config)
      : world(std::make_shared<World>(std::move(config))), dome("dome", world), camera("cam", world) {
    EXPECT_TRUE(dome.Open().ok());
    EXPECT_TRUE(camera.Open().ok());
    EXPECT_TRUE(camera.Configure(drivers::CameraSettings{}).ok());
    EXPECT_TRUE(camera.Start().ok());
  }
  Result<drivers::Frame> Capture() {
    if (Status s = camera.Trigger(); !s.ok()) return s;
    return camera.WaitFrame(100);
  }
};

WorldConfig Config() {
  WorldConfig config;
  config.camera = {16, 16, 1.0};
  config.lights = {{Eigen::Vector3d(0, 0, 1), 1.0}, {Eigen::Vector3d(0.6, 0, 0.8), 1.0}};
  return config;
}

TEST(SimFaults, DroppedShortAndCorruptFramesAreReportedAsSuch) {
  WorldConfig config = Config();
  config.camera_faults.drop_frames = {1};
  config.camera_faults.short_frames = {2};
  config.camera_faults.corrupt_frames = {3};
  FaultyRig rig(config);
  auto first = rig.Capture();
  ASSERT_TRUE(first.ok());
  EXPECT_EQ(rig.Capture().status().code(), StatusCode::kTimeout);
  EXPECT_EQ(rig.Capture().status().code(), StatusCode::kDataLoss);
  EXPECT_EQ(rig.Capture().status().code(), StatusCode::kDataLoss);
  auto fifth = rig.Capture();
  ASSERT_TRUE(fifth.ok());
  EXPECT_EQ(fifth->frame_id, first->frame_id + 4);  // the gap shows the dropped frame
}

TEST(SimFaults, DisconnectLastsUntilReopen) {
  WorldConfig config = Config();
  config.camera_faults.disconnect_at = {1};
  FaultyRig rig(config);
  ASSERT_TRUE(rig.Capture().ok());
  EXPECT_EQ(rig.Capture().status().code(), StatusCode::kUnavailable);
  EXPECT_EQ(rig.Capture().status().code(), StatusCode::kUnavailable);
  ASSERT_TRUE(rig.camera.Close().ok());
  ASSERT_TRUE(rig.camera.Open().ok());
  ASSERT_TRUE(rig.camera.Configure(drivers::CameraSettings{}).ok());
  ASSERT_TRUE(rig.camera.Start().ok());
  EXPECT_TRUE(rig.Capture().ok());
}

TEST(SimFaults, LightCommandFailuresAndStuckLeds) {
  WorldConfig config = Config();
  config.light_faults.fail_commands = {2};  // command 0 is Open's all-off
  config.light_faults.stuck_off_channels = {1};
  FaultyRig rig(config);
  EXPECT_TRUE(rig.dome.SetPattern({{1.0, 1.0}}).ok());
  EXPECT_EQ(rig.world->levels(), (std::vector<double>{1.0, 0.0}));
  EXPECT_EQ(rig.dome.SetPattern({{1.0, 0.0}}).code(), StatusCode::kUnavailable);
}

}  // namespace
}  // namespace photorig::sim
