// The safety wrapper in front of a real driver (GPIO on in-memory chips):
// on-time and duty-cycle limits, the sequencer watchdog, and the exit net.

#include "photorig/drivers/gpio/internal/gpio_memory.h"
#include "photorig/drivers/light_safety.h"
#include "photorig/drivers/internal/safety_net.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <thread>

namespace photorig::drivers {
namespace {

using namespace std::chrono_literals;

struct Dome {
  std::shared_ptr<InMemoryGpioChips> chips = std::make_shared<InMemoryGpioChips>();
  std::unique_ptr<SafeLightController> lights;
  explicit Dome(LightSafetyOptions options) {
    chips->AddChip("gpiochip0", 8);
    std::vector<GpioLine> lines;
    for (unsigned i = 0; i < 3; ++i) lines.push_back({"gpiochip0", i, false});
    lights = std::make_unique<SafeLightController>(
        std::make_unique<GpioLightController>("dome", lines, chips->MakeBackend()), options);
  }
  int lit(unsigned line) const { return chips->physical("gpiochip0", line); }
};

LightPattern Only(int channel) { return LightPattern::Single(3, channel, 1.0); }

TEST(LightSafety, InvalidLimitsAreRefusedAtOpen) {
  LightSafetyOptions options;
  options.defaults.max_duty = 0.0;
  Dome dome(options);
  const Status status = dome.lights->Open();
  EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(status.message().find("max_duty"), std::string::npos);
}

TEST(LightSafety, ChannelLeftOnPastItsMaximumOnTimeIsCut) {
  LightSafetyOptions options;
  options.defaults.max_on_ms = 1000;
  options.per_channel = {options.defaults, {60.0, 1.0}, options.defaults};  // channel 1: 60 ms
  Dome dome(options);
  ASSERT_TRUE(dome.lights->Open().ok());
  LightPattern both = LightPattern::AllOff(3);
  both.levels[0] = both.levels[1] = 1.0;
  ASSERT_TRUE(dome.lights->SetPattern(both).ok());
  EXPECT_EQ(dome.lit(1), 1);
  std::this_thread::sleep_for(150ms);
  EXPECT_EQ(dome.lit(1), 0);  // cut by the monitor, no command needed
  EXPECT_EQ(dome.lit(0), 1);  // within its own limit
  ASSERT_EQ(dome.lights->cuts().size(), 1u);
  EXPECT_NE(dome.lights->cuts()[0].find("channel 1: on-time"), std::string::npos) << dome.lights->cuts()[0];
  // The next command hears about it.
  const Status next = dome.lights->SetPattern(both);
  EXPECT_EQ(next.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(next.message().find("safety limit: channel 1"), std::string::npos) << next.message();
}

TEST(LightSafety, PatternKeepingAChannelOnTooLongIsRefusedForThatChannel) {
  LightSafetyOptions options;
  options.defaults.max_on_ms = 80;
  options.monitor_period_ms = 1000;  // slow monitor: the refusal must come from SetPattern itself
  Dome dome(options);
  ASSERT_TRUE(dome.lights->Open().ok());
  ASSERT_TRUE(dome.lights->SetPattern(Only(2)).ok());
  std::this_thread::sleep_for(100ms);
  LightPattern more = Only(2);
  more.levels[0] = 1.0;
  const Status status = dome.lights->SetPattern(more);
  EXPECT_EQ(status.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(status.message().find("channel 2: on-time"), std::string::npos) << status.message();
  EXPECT_EQ(dome.lit(2), 0);  // cut
  EXPECT_EQ(dome.lit(0), 1);  // the rest of the pattern applies
}

TEST(LightSafety, DutyCycleOverTheWindowIsEnforced) {
  LightSafetyOptions options;
  options.defaults.max_duty = 0.25;
  options.duty_window_ms = 400;  // 100 ms of light per 400 ms window
  Dome dome(options);
  ASSERT_TRUE(dome.lights->Open().ok());
  ASSERT_TRUE(dome.lights->SetPattern(Only(0)).ok());
  std::this_thread::sleep_for(60ms);
  ASSERT_TRUE(dome.lights->AllOff().ok());
  ASSERT_TRUE(dome.lights->SetPattern(Only(0)).ok());  // 60 ms used, allowed
  std::this_thread::sleep_for(80ms);                  // crosses 100 ms: cut
  EXPECT_EQ(dome.lit(0), 0);
  const Status again = dome.lights->SetPattern(Only(0));
  EXPECT_EQ(again.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(again.message().find("duty"), std::string::npos) << again.message();
  EXPECT_TRUE(dome.lights->SetPattern(Only(1)).ok());  // other channels have their own budget
  ASSERT_TRUE(dome.lights->AllOff().ok());
  std::this_thread::sleep_for(450ms);  // the window slides past the old on-time
  EXPECT_TRUE(dome.lights->SetPattern(Only(0)).ok());
  EXPECT_EQ(dome.lit(0), 1);
}

TEST(LightSafety, WatchdogSwitchesOffWhenTheSequencerStalls) {
  LightSafetyOptions options;
  options.watchdog_ms = 80;
  Dome dome(options);
  ASSERT_TRUE(dome.lights->Open().ok());
  ASSERT_TRUE(dome.lights->SetPattern(Only(1)).ok());
  for (int i = 0; i < 4; ++i) {  // heartbeats keep it alive
    std::this_thread::sleep_for(40ms);
    dome.lights->Heartbeat();
  }
  EXPECT_EQ(dome.lit(1), 1);
  std::this_thread::sleep_for(150ms);  // silence
  EXPECT_EQ(dome.lit(1), 0);
  ASSERT_FALSE(dome.lights->cuts().empty());
  EXPECT_NE(dome.lights->cuts()[0].find("watchdog"), std::string::npos);
}

TEST(LightSafety, CloseAndDestructionLeaveTheDomeDarkAndTheNetEmpty) {
  Dome dome({});
  ASSERT_TRUE(dome.lights->Open().ok());
  EXPECT_EQ(SafetyNet::size(), 1);
  ASSERT_TRUE(dome.lights->SetPattern(Only(2)).ok());
  dome.lights.reset();
  EXPECT_EQ(dome.lit(2), 0);
  EXPECT_EQ(SafetyNet::size(), 0);
}

// A process that exits, or dies in std::terminate, with the lights on leaves
// them off. Each case runs in a freshly executed child (death-test style
// "threadsafe"), whose own report runs after the net: an atexit handler
// registered before the net's (handlers run in reverse), and the terminate
// handler the net chains to.
Dome* g_dome = nullptr;

TEST(SafetyNetDeathTest, ExitSwitchesOpenLightsOff) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        g_dome = new Dome({});  // deliberately never closed
        std::atexit([] { std::fprintf(stderr, "after exit: %d\n", g_dome->lit(1)); });
        if (!g_dome->lights->Open().ok() || !g_dome->lights->SetPattern(Only(1)).ok()) std::_Exit(2);
        std::fprintf(stderr, "before exit: %d\n", g_dome->lit(1));
        std::exit(0);
      },
      ::testing::ExitedWithCode(0), "before exit: 1\n(.|\n)*after exit: 0");
}

TEST(SafetyNetDeathTest, TerminateSwitchesOpenLightsOff) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        g_dome = new Dome({});
        std::set_terminate([] {
          std::fprintf(stderr, "after terminate: %d\n", g_dome->lit(1));
          std::_Exit(3);
        });
        if (!g_dome->lights->Open().ok() || !g_dome->lights->SetPattern(Only(1)).ok()) std::_Exit(2);
        std::terminate();
      },
      ::testing::ExitedWithCode(3), "after terminate: 0");
}

}  // namespace
}  // namespace photorig::drivers
