#pragma once
// A LightController that any driver can be put behind to enforce the rig's
// LED safety limits in the driver layer, whatever the caller does:
//   - maximum continuous on-time per channel: a pattern that would keep a
//     channel on past it is refused, and a channel left on past it is cut;
//   - maximum duty cycle per channel over a sliding window: switching on a
//     channel whose window is already used up is refused; it is cut when the
//     window fills while it is on;
//   - a watchdog: if no SetPattern or Heartbeat arrives within the timeout
//     while any channel is lit (a stalled sequencer), everything goes off;
//   - the inner controller's hardware dead-man kept alive every
//     keepalive_period_ms while this process lives, so that a process killed
//     outright (SIGKILL, a crash) leaves the hardware to switch itself off.
// Cuts happen on a monitor thread; the refusal or cut is reported by the next
// SetPattern (kFailedPrecondition naming the channel and the limit).
// The wrapper also registers with the SafetyNet while open.

#include "photorig/drivers/light_controller.h"

#include <chrono>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace photorig::drivers {

struct ChannelLimits {
  double max_on_ms = 0.0;  // 0 = unlimited
  double max_duty = 1.0;   // fraction of duty_window_ms a channel may be on, in (0, 1]
};

struct LightSafetyOptions {
  // Defaults that suit LEDs of a dome in normal use (frames of up to seconds,
  // a few LEDs lit at once); a rig with other needs says so in its YAML.
  ChannelLimits defaults{.max_on_ms = 10000.0, .max_duty = 0.5};
  std::vector<ChannelLimits> per_channel;  // empty, or one entry per channel (overrides defaults)
  double duty_window_ms = 10000.0;
  double watchdog_ms = 5000.0;  // 0 = no watchdog
  int monitor_period_ms = 5;
  int keepalive_period_ms = 250;  // well inside any hardware dead-man's timeout (>= 1 s by convention)

  bool IsValid(int channels, std::string* why) const;
  const ChannelLimits& For(int channel) const {
    return per_channel.empty() ? defaults : per_channel.at(channel);
  }
};

class SafeLightController : public LightController {
 public:
  SafeLightController(std::unique_ptr<LightController> inner, LightSafetyOptions options);
  ~SafeLightController() override;
  int channel_count() const override { return inner_->channel_count(); }

  // Tells the watchdog the sequencer is alive without changing the pattern
  // (also what KeepAlive does, besides keeping the hardware dead-man alive).
  void Heartbeat();
  // Every cut made by the monitor so far ("channel 3: on-time 520 ms > 500 ms").
  std::vector<std::string> cuts() const;
  LightController& inner() { return *inner_; }

 protected:
  Status DoOpen() override;
  Status DoSetPattern(const LightPattern& pattern) override;
  Result<LightPattern> DoReadBack() override;
  Status DoClose() override;
  Status DoKeepAlive() override;

 private:
  using Clock = std::chrono::steady_clock;
  struct Channel {
    bool on = false;
    Clock::time_point on_since;
    std::deque<std::pair<Clock::time_point, Clock::time_point>> history;  // past on-intervals in the window
  };
  double OnTimeInWindowMs(const Channel& channel, Clock::time_point now) const;
  // Empty if the channel may be on at `now`, else why not.
  std::string Violation(int index, Clock::time_point now, bool switching_on) const;
  Status ApplyLocked(const LightPattern& pattern, Clock::time_point now);
  void Monitor();

  std::unique_ptr<LightController> inner_;
  LightSafetyOptions options_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::vector<Channel> channels_;
  LightPattern current_;
  Clock::time_point last_command_;
  Clock::time_point last_keepalive_;
  std::vector<std::string> cuts_;
  std::string pending_report_;  // a cut not yet reported to the caller
  bool stopping_ = false;
  std::thread monitor_;
};

}  // namespace photorig::drivers
