// GPIO LEDs and trigger lines through the libgpiod seam, on in-memory chips
// that behave like the kernel's (physical levels, busy lines).

#include "photorig/drivers/gpio/internal/gpio_memory.h"
#include "photorig/drivers/light_safety.h"

#include <gtest/gtest.h>

#include <chrono>
#include <thread>

namespace photorig::drivers {
namespace {

std::shared_ptr<InMemoryGpioChips> Chips() {
  auto chips = std::make_shared<InMemoryGpioChips>();
  chips->AddChip("gpiochip0", 32);
  chips->AddChip("gpiochip1", 8);
  return chips;
}

std::vector<GpioLine> Lines() {
  return {{"gpiochip0", 4, false}, {"gpiochip0", 5, true}, {"gpiochip1", 2, false}, {"gpiochip0", 17, true}};
}

TEST(GpioLights, OpenStartsDarkWithActiveLowLinesHigh) {
  auto chips = Chips();
  GpioLightController lights("dome", Lines(), chips->MakeBackend());
  ASSERT_TRUE(lights.Open().ok());
  EXPECT_EQ(chips->physical("gpiochip0", 4), 0);
  EXPECT_EQ(chips->physical("gpiochip0", 5), 1);  // active-low: off = high
  EXPECT_EQ(chips->physical("gpiochip1", 2), 0);
  EXPECT_EQ(chips->physical("gpiochip0", 17), 1);
  EXPECT_TRUE(chips->requested("gpiochip0", 17));
}

TEST(GpioLights, PatternSetsPhysicalLevelsInOneBulkCallAndReadsBack) {
  auto chips = Chips();
  GpioLightController lights("dome", Lines(), chips->MakeBackend());
  ASSERT_TRUE(lights.Open().ok());
  const int calls = chips->bulk_calls();
  ASSERT_TRUE(lights.SetPattern({{0.0, 0.4, 1.0, 0.0}}).ok());
  EXPECT_EQ(chips->bulk_calls(), calls + 1);
  EXPECT_EQ(chips->physical("gpiochip0", 4), 0);
  EXPECT_EQ(chips->physical("gpiochip0", 5), 0);  // lit active-low line is pulled low
  EXPECT_EQ(chips->physical("gpiochip1", 2), 1);
  EXPECT_EQ(chips->physical("gpiochip0", 17), 1);
  auto back = lights.ReadBack();
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back->levels, (std::vector<double>{0.0, 1.0, 1.0, 0.0}));  // GPIO is on/off
}

TEST(GpioLights, CloseSwitchesOffAndReleases) {
  auto chips = Chips();
  {
    GpioLightController lights("dome", Lines(), chips->MakeBackend());
    ASSERT_TRUE(lights.Open().ok());
    ASSERT_TRUE(lights.SetPattern({{1.0, 1.0, 1.0, 1.0}}).ok());
    ASSERT_TRUE(lights.Close().ok());
    EXPECT_FALSE(chips->requested("gpiochip0", 4));
    EXPECT_EQ(chips->physical("gpiochip0", 4), 0);
    EXPECT_EQ(chips->physical("gpiochip0", 5), 1);
    // Destroyed while open: the destructor closes.
    ASSERT_TRUE(lights.Open().ok());
    ASSERT_TRUE(lights.SetPattern({{0.0, 0.0, 1.0, 0.0}}).ok());
  }
  EXPECT_EQ(chips->physical("gpiochip1", 2), 0);
  EXPECT_FALSE(chips->requested("gpiochip1", 2));
}

// A process that dies leaves released lines as the chip keeps them: the
// heartbeat line's edges are what an external watchdog powering the LEDs sees stop.
TEST(GpioLights, KeepAliveTogglesTheHeartbeatLineAndNothingElse) {
  auto chips = Chips();
  GpioLightController lights("dome", Lines(), chips->MakeBackend(), GpioLine{"gpiochip1", 7, false});
  EXPECT_EQ(lights.channel_count(), 4);
  ASSERT_TRUE(lights.Open().ok());
  EXPECT_TRUE(chips->requested("gpiochip1", 7));
  EXPECT_EQ(chips->physical("gpiochip1", 7), 0);
  ASSERT_TRUE(lights.SetPattern({{1.0, 0.0, 0.0, 0.0}}).ok());
  EXPECT_EQ(chips->physical("gpiochip1", 7), 0);  // a pattern is no heartbeat
  for (int level : {1, 0, 1}) {
    ASSERT_TRUE(lights.KeepAlive().ok());
    EXPECT_EQ(chips->physical("gpiochip1", 7), level);
    EXPECT_EQ(chips->physical("gpiochip0", 4), 1);  // the lit LED stays lit
    EXPECT_EQ(chips->physical("gpiochip0", 5), 1);
  }
  auto back = lights.ReadBack();
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back->levels, (std::vector<double>{1.0, 0.0, 0.0, 0.0}));
  ASSERT_TRUE(lights.Close().ok());
  EXPECT_FALSE(chips->requested("gpiochip1", 7));
  EXPECT_EQ(chips->physical("gpiochip0", 4), 0);
}

TEST(GpioLights, TheSafetyLayerKeepsTheHeartbeatGoingWhileOpen) {
  auto chips = Chips();
  LightSafetyOptions options;
  options.keepalive_period_ms = 10;
  SafeLightController lights(
      std::make_unique<GpioLightController>("dome", Lines(), chips->MakeBackend(), GpioLine{"gpiochip1", 7, true}),
      options);
  ASSERT_TRUE(lights.Open().ok());
  // The recorded levels of the heartbeat line, oldest first. Read from the record, not the line's
  // level now: the monitor may already have toggled it by the time this thread runs again.
  auto levels = [&] {
    std::vector<int> seen;
    for (const InMemoryGpioChips::Change& change : chips->changes())
      if (change.chip == "gpiochip1" && change.offset == 7) seen.push_back(change.physical);
    return seen;
  };
  auto edges = [&] { return static_cast<int>(levels().size()); };
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(30);  // a hang guard, not a measurement
  while (edges() < 4 && std::chrono::steady_clock::now() < give_up)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  const std::vector<int> seen = levels();
  ASSERT_GE(seen.size(), 4u);
  EXPECT_EQ(seen.front(), 1);  // active-low heartbeat: it starts at logical 0, high
  for (std::size_t i = 1; i < seen.size(); ++i) EXPECT_NE(seen[i], seen[i - 1]) << "keep-alive " << i << " is no edge";
  ASSERT_TRUE(lights.Close().ok());
  const int after_close = edges();
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(edges(), after_close) << "the heartbeat went on after Close";
  EXPECT_FALSE(chips->requested("gpiochip1", 7));
}

TEST(GpioLights, MissingOrBusyLineFailsOpenNamingIt) {
  auto chips = Chips();
  GpioLightController bad("dome", {{"gpiochip1", 9, false}}, chips->MakeBackend());
  const Status missing = bad.Open();
  EXPECT_EQ(missing.code(), StatusCode::kUnavailable);
  EXPECT_NE(missing.message().find("gpiochip1:9"), std::string::npos) << missing.message();
  EXPECT_NE(missing.message().find("light controller dome"), std::string::npos);

  GpioLightController first("a", Lines(), chips->MakeBackend());
  ASSERT_TRUE(first.Open().ok());
  GpioLightController second("b", {{"gpiochip0", 5, false}}, chips->MakeBackend());
  const Status busy = second.Open();
  EXPECT_NE(busy.message().find("busy"), std::string::npos) << busy.message();
}

TEST(GpioTrigger, PulseHasTheRequestedWidthAndEndsDeasserted) {
  auto chips = Chips();
  GpioTriggerLine trigger("cam-trigger", {"gpiochip1", 7, true}, chips->MakeBackend());
  EXPECT_EQ(trigger.Fire(std::chrono::microseconds(100)).code(), StatusCode::kFailedPrecondition);
  ASSERT_TRUE(trigger.Open().ok());
  EXPECT_EQ(chips->physical("gpiochip1", 7), 1);  // active-low, idle high
  ASSERT_TRUE(trigger.Fire(std::chrono::microseconds(3000)).ok());
  const auto changes = chips->changes();
  ASSERT_GE(changes.size(), 3u);
  const auto& assert_edge = changes[changes.size() - 2];
  const auto& release_edge = changes.back();
  EXPECT_EQ(assert_edge.physical, 0);
  EXPECT_EQ(release_edge.physical, 1);
  const auto width_us =
      std::chrono::duration_cast<std::chrono::microseconds>(release_edge.when - assert_edge.when).count();
  EXPECT_GE(width_us, 3000);
  EXPECT_EQ(trigger.Fire(std::chrono::microseconds(0)).code(), StatusCode::kInvalidArgument);
  ASSERT_TRUE(trigger.Close().ok());
  EXPECT_FALSE(chips->requested("gpiochip1", 7));
  EXPECT_EQ(chips->physical("gpiochip1", 7), 1);
}

TEST(GpioTrigger, IllegalTransitionsKeepTheLineAsItWas) {
  auto chips = Chips();
  {
    GpioTriggerLine trigger("cam-trigger", {"gpiochip0", 9, false}, chips->MakeBackend());
    ASSERT_TRUE(trigger.Open().ok());
    const int calls = chips->bulk_calls();
    // A second open is refused by the state machine, not by the kernel as a busy line.
    const Status again = trigger.Open();
    EXPECT_EQ(again.code(), StatusCode::kFailedPrecondition);
    EXPECT_NE(again.message().find("cannot open while open"), std::string::npos) << again.message();
    EXPECT_EQ(chips->bulk_calls(), calls);
    EXPECT_TRUE(chips->requested("gpiochip0", 9));
    EXPECT_EQ(chips->physical("gpiochip0", 9), 0);
    ASSERT_TRUE(trigger.Close().ok());
    ASSERT_TRUE(trigger.Close().ok());
    EXPECT_EQ(trigger.Fire(std::chrono::microseconds(100)).code(), StatusCode::kFailedPrecondition);
    EXPECT_EQ(chips->physical("gpiochip0", 9), 0);
    // Destroyed while open: the destructor deasserts and releases.
    ASSERT_TRUE(trigger.Open().ok());
  }
  EXPECT_FALSE(chips->requested("gpiochip0", 9));
  EXPECT_EQ(chips->physical("gpiochip0", 9), 0);
}

TEST(GpioLibgpiod, AbsentChipIsAClearError) {
  GpioLightController lights("dome", {{"gpiochip-none", 0, false}}, MakeLibgpiodBackend());
  const Status status = lights.Open();
  EXPECT_EQ(status.code(), StatusCode::kUnavailable);
  EXPECT_NE(status.message().find("cannot open GPIO chip 'gpiochip-none'"), std::string::npos) << status.message();
}

}  // namespace
}  // namespace photorig::drivers
