// The Modbus drive profile and the Motion state machine against the
// simulated arms over Modbus TCP, including stall and overshoot faults and
// the arm-collision constraint.

#include "photorig/drivers/motion/goniometer.h"
#include "photorig/drivers/motion/modbus_drive.h"
#include "photorig/drivers/internal/safety_net.h"
#include "photorig/sim/modbus/internal/arm_peer.h"
#include "photorig/sim/modbus/server.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>

namespace photorig {
namespace {

using drivers::Motion;
using State = drivers::Motion::State;

struct Arms {
  std::vector<std::shared_ptr<sim::SimArm>> sims;
  sim::SimModbusServer server;
  std::vector<std::unique_ptr<drivers::ModbusDriveAxis>> axes;

  // homes: each axis's home_deg on the rig (the drives count from 0 there).
  explicit Arms(sim::SimArmOptions base = {}, std::array<double, 3> homes = {0.0, 0.0, 0.0}) {
    int address = 1000;
    for (const char* name : {"light_arm", "camera_arm", "sample_stage"}) {
      sim::SimArmOptions options = base;
      options.name = name;
      options.base_address = address;
      options.initial_position_deg = address == 1000 ? -40.0 : address == 1100 ? 35.0 : 3.0;
      sims.push_back(std::make_shared<sim::SimArm>(options));
      server.AddPeer(sims.back());
      address += 100;
    }
    EXPECT_TRUE(server.StartTcp().ok());
    drivers::ModbusLinkOptions link;
    link.port = server.port();
    drivers::SettleOptions settle;
    settle.timeout_ms = 3000;
    settle.stall_window_ms = 150;
    address = 1000;
    for (const char* name : {"light_arm", "camera_arm", "sample_stage"}) {
      axes.push_back(std::make_unique<drivers::ModbusDriveAxis>(
          name, link, address, drivers::AxisLimits{-120, 120, homes[(address - 1000) / 100]}, settle));
      address += 100;
    }
  }
};

const drivers::MotionProfile kFast{400.0, 4000.0};

TEST(ModbusDrive, RegisterEncodingRoundTripsNegativeMillidegrees) {
  std::uint16_t words[2];
  drivers::drive_profile::EncodeMillidegrees(-123.456, words);
  EXPECT_EQ(words[0], 0xFFFE);  // -123456 = 0xFFFE1DC0
  EXPECT_EQ(words[1], 0x1DC0);
  EXPECT_DOUBLE_EQ(drivers::drive_profile::DecodeMillidegrees(words), -123.456);
}

TEST(ModbusDrive, StateMachineHomesMovesAndSettles) {
  Arms arms;
  Motion& arm = *arms.axes[0];
  EXPECT_EQ(arm.Home().code(), StatusCode::kFailedPrecondition);  // closed
  ASSERT_TRUE(arm.Open().ok());
  EXPECT_EQ(arm.state(), State::kOpen);
  EXPECT_EQ(drivers::SafetyNet::size(), 1);
  const Status before_homing = arm.MoveTo(10.0);
  EXPECT_EQ(before_homing.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(before_homing.message().find("before homing"), std::string::npos);
  ASSERT_TRUE(arm.Home().ok());
  EXPECT_EQ(arm.state(), State::kIdle);
  EXPECT_TRUE(arms.sims[0]->homed());
  EXPECT_NEAR(arms.sims[0]->position_deg(), 0.0, 1e-6);

  const Status moved = arm.MoveTo(-25.5, kFast);
  ASSERT_TRUE(moved.ok()) << moved.ToString();
  EXPECT_EQ(arm.state(), State::kIdle);
  EXPECT_NEAR(arms.sims[0]->position_deg(), -25.5, 1e-3);
  auto polled = arm.Poll();
  ASSERT_TRUE(polled.ok());
  EXPECT_NEAR(polled->position_deg, -25.5, 1e-3);
  EXPECT_FALSE(polled->busy);

  const Status outside = arm.MoveTo(150.0, kFast);  // soft limit 120
  EXPECT_EQ(outside.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(outside.message().find("outside soft limits"), std::string::npos);
  EXPECT_EQ(arm.state(), State::kIdle);
  EXPECT_EQ(arms.sims[0]->moves(), 1u);  // nothing was sent

  ASSERT_TRUE(arm.Close().ok());
  EXPECT_EQ(arm.state(), State::kClosed);
  EXPECT_EQ(drivers::SafetyNet::size(), 0);
}

TEST(ModbusDrive, StallIsDetectedAndTheAxisStopsInFault) {
  sim::SimArmOptions options;
  options.stall_moves = {1};  // the second move
  Arms arms(options);
  Motion& arm = *arms.axes[1];
  ASSERT_TRUE(arm.Open().ok());
  ASSERT_TRUE(arm.Home().ok());
  ASSERT_TRUE(arm.MoveTo(10.0, kFast).ok());
  const Status stalled = arm.MoveTo(50.0, kFast);
  EXPECT_EQ(stalled.code(), StatusCode::kInternal);
  EXPECT_NE(stalled.message().find("stalled"), std::string::npos) << stalled.message();
  EXPECT_NE(stalled.message().find("camera_arm"), std::string::npos);
  EXPECT_EQ(arm.state(), State::kFault);
  EXPECT_NEAR(arms.sims[1]->position_deg(), 30.0, 1e-3);  // half way, where the motor stopped
  auto polled = arm.Poll();
  ASSERT_TRUE(polled.ok());
  EXPECT_FALSE(polled->busy);  // the fault path sent Stop
  // Illegal until the fault is cleared and the axis homed again.
  EXPECT_EQ(arm.MoveTo(0.0, kFast).code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(arm.Home().code(), StatusCode::kFailedPrecondition);
  ASSERT_TRUE(arm.ClearFault().ok());
  EXPECT_EQ(arm.state(), State::kOpen);
  ASSERT_TRUE(arm.Home().ok());
  EXPECT_TRUE(arm.MoveTo(20.0, kFast).ok());
}

TEST(ModbusDrive, OvershootIsDetected) {
  sim::SimArmOptions options;
  options.overshoot_moves = {0};
  options.overshoot_deg = 3.0;
  Arms arms(options);
  Motion& stage = *arms.axes[2];
  ASSERT_TRUE(stage.Open().ok());
  ASSERT_TRUE(stage.Home().ok());
  const Status status = stage.MoveTo(-30.0, kFast);
  EXPECT_EQ(status.code(), StatusCode::kInternal);
  EXPECT_NE(status.message().find("overshoot"), std::string::npos) << status.message();
  EXPECT_EQ(stage.state(), State::kFault);
  EXPECT_LT(arms.sims[2]->position_deg(), -30.5);
}

TEST(ModbusDrive, HardLimitSwitchFaultsTheAxis) {
  sim::SimArmOptions options;
  options.hard_max_deg = 60.0;  // the switch sits inside the soft limit of 120
  Arms arms(options);
  Motion& arm = *arms.axes[0];
  ASSERT_TRUE(arm.Open().ok());
  ASSERT_TRUE(arm.Home().ok());
  const Status status = arm.MoveTo(100.0, kFast);
  EXPECT_NE(status.message().find("drive fault"), std::string::npos) << status.message();
  EXPECT_NE(status.message().find("limit switch"), std::string::npos) << status.message();
  EXPECT_NEAR(arms.sims[0]->position_deg(), 60.0, 1e-6);
}

TEST(ModbusDrive, CloseStopsAMovingArm) {
  Arms arms;
  auto& arm = *arms.axes[0];
  ASSERT_TRUE(arm.Open().ok());
  ASSERT_TRUE(arm.Home().ok());
  // Start a long, slow move behind the state machine's back, as a crashed
  // process would leave it, then close: the drive must be stopped.
  drivers::ModbusLink raw("test", [&] {
    drivers::ModbusLinkOptions link;
    link.port = arms.server.port();
    return link;
  }());
  std::vector<std::uint16_t> block(5);
  drivers::drive_profile::EncodeMillidegrees(100.0, block.data());
  block[2] = 100;  // 10 deg/s
  block[3] = 1000;
  block[4] = drivers::drive_profile::kMove;
  ASSERT_TRUE(raw.WriteRegisters(1000, block).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  ASSERT_TRUE(arm.Close().ok());
  const double stopped_at = arms.sims[0]->position_deg();
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  auto status = raw.ReadRegisters(1000 + drivers::drive_profile::kStatus, 1);
  ASSERT_TRUE(status.ok());
  EXPECT_EQ(status.value()[0] & drivers::drive_profile::kBusy, 0);
  EXPECT_NEAR(arms.sims[0]->position_deg(), stopped_at, 1e-9);
  EXPECT_LT(stopped_at, 5.0);
}

double RigPosition(drivers::Motion& axis) {
  Result<drivers::AxisStatus> polled = axis.Poll();
  EXPECT_TRUE(polled.ok()) << polled.status().message();
  return polled.ok() ? polled->position_deg : NAN;
}

// The light arm homes at -60 deg and the camera arm at +60 on the rig; their
// drives count from 0 at those homes.
TEST(Goniometer, KeepsArmsApartAndPicksASafeOrder) {
  Arms arms({}, {-60.0, 60.0, 0.0});
  std::vector<drivers::Motion*> axes;
  for (auto& axis : arms.axes) axes.push_back(axis.get());
  drivers::Goniometer gonio(axes, {{"light_arm", "camera_arm", 15.0}});
  ASSERT_TRUE(gonio.Validate().ok());
  for (auto& axis : arms.axes) ASSERT_TRUE(axis->Open().ok());
  ASSERT_TRUE(gonio.HomeAll().ok());
  EXPECT_NEAR(RigPosition(*arms.axes[0]), -60.0, 1e-6);
  EXPECT_NEAR(RigPosition(*arms.axes[1]), 60.0, 1e-6);
  EXPECT_NEAR(arms.sims[0]->position_deg(), 0.0, 1e-6);  // the drive's own count
  ASSERT_TRUE(gonio.MoveTo({{"light_arm", -30.0}}, kFast).ok());
  ASSERT_TRUE(gonio.MoveTo({{"camera_arm", 30.0}}, kFast).ok());
  EXPECT_NEAR(arms.sims[0]->position_deg(), 30.0, 1e-3);  // -30 on the rig is 30 from the home switch

  // Too close at the end: refused, nothing moves.
  const std::uint64_t moves = arms.sims[0]->moves() + arms.sims[1]->moves();
  const Status close = gonio.MoveTo({{"light_arm", 20.0}}, kFast);
  EXPECT_EQ(close.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(close.message().find("light_arm and camera_arm would be 10.000 deg apart"), std::string::npos)
      << close.message();
  EXPECT_EQ(arms.sims[0]->moves() + arms.sims[1]->moves(), moves);

  // Swapping sides would sweep one arm through the other in any order: refused.
  const Status swap = gonio.MoveTo({{"light_arm", 60.0}, {"camera_arm", -60.0}}, kFast);
  EXPECT_EQ(swap.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(swap.message().find("no collision-free order"), std::string::npos) << swap.message();

  // Both move the same way: only the camera-first order keeps them apart.
  ASSERT_TRUE(gonio.MoveTo({{"light_arm", 40.0}, {"camera_arm", 70.0}}, kFast).ok());
  EXPECT_NEAR(RigPosition(*arms.axes[0]), 40.0, 1e-3);
  EXPECT_NEAR(RigPosition(*arms.axes[1]), 70.0, 1e-3);
  EXPECT_TRUE(gonio.CloseAll().ok());
}

TEST(Goniometer, HomesInAnOrderThatKeepsArmsApart) {
  Arms arms({}, {-60.0, 60.0, 0.0});
  // Camera arm listed first: homing in the given order would swing it onto the light arm below.
  std::vector<drivers::Motion*> axes{arms.axes[1].get(), arms.axes[0].get(), arms.axes[2].get()};
  drivers::Goniometer gonio(axes, {{"light_arm", "camera_arm", 15.0}});
  for (auto& axis : arms.axes) ASSERT_TRUE(axis->Open().ok());
  ASSERT_TRUE(gonio.HomeAll().ok());  // from power-on: the given order, both arms away from each other
  ASSERT_TRUE(gonio.MoveTo({{"light_arm", 50.0}, {"camera_arm", 70.0}}, kFast).ok());
  // Camera first would stop it at 60, 10 deg from the light arm at 50: the light arm must go first.
  const Status homed = gonio.HomeAll();
  ASSERT_TRUE(homed.ok()) << homed.message();
  EXPECT_NEAR(RigPosition(*arms.axes[0]), -60.0, 1e-6);
  EXPECT_NEAR(RigPosition(*arms.axes[1]), 60.0, 1e-6);
  EXPECT_TRUE(gonio.CloseAll().ok());
}

TEST(Goniometer, RefusesToHomeArmsWhoseHomesCollide) {
  Arms arms({}, {0.0, 5.0, 0.0});  // power-on at -40 and 35 deg on the drives
  std::vector<drivers::Motion*> axes;
  for (auto& axis : arms.axes) axes.push_back(axis.get());
  drivers::Goniometer gonio(axes, {{"light_arm", "camera_arm", 15.0}});
  for (auto& axis : arms.axes) ASSERT_TRUE(axis->Open().ok());
  const Status homed = gonio.HomeAll();
  EXPECT_EQ(homed.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(homed.message().find("at their homes light_arm and camera_arm would be 5.000 deg apart"),
            std::string::npos)
      << homed.message();
  // Nothing moved.
  EXPECT_NEAR(arms.sims[0]->position_deg(), -40.0, 1e-9);
  EXPECT_NEAR(arms.sims[1]->position_deg(), 35.0, 1e-9);
  EXPECT_EQ(arms.axes[0]->state(), State::kOpen);
  EXPECT_TRUE(gonio.CloseAll().ok());
}

}  // namespace
}  // namespace photorig
