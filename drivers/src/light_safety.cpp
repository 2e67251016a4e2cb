#include "photorig/drivers/light_safety.h"

#include "photorig/drivers/internal/safety_net.h"

#include <algorithm>
#include <cstdio>

namespace photorig::drivers {
namespace {

double Ms(std::chrono::steady_clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); }

std::string Fmt(const char* format, double a, double b) {
  char text[96];
  std::snprintf(text, sizeof(text), format, a, b);
  return text;
}

}  // namespace

bool LightSafetyOptions::IsValid(int channels, std::string* why) const {
  if (!per_channel.empty() && static_cast<int>(per_channel.size()) != channels)
    return Refuse(why, "per-channel limits list " + std::to_string(per_channel.size()) + " entries for " +
                           std::to_string(channels) + " channels");
  std::vector<ChannelLimits> all = per_channel;
  all.push_back(defaults);
  for (const ChannelLimits& limits : all) {
    if (!(limits.max_on_ms >= 0)) return Refuse(why, "max_on_ms must be >= 0");
    if (!(limits.max_duty > 0 && limits.max_duty <= 1)) return Refuse(why, "max_duty must be within (0, 1]");
  }
  if (!(duty_window_ms > 0)) return Refuse(why, "duty_window_ms must be > 0");
  if (!(watchdog_ms >= 0)) return Refuse(why, "watchdog_ms must be >= 0");
  if (monitor_period_ms <= 0) return Refuse(why, "monitor_period_ms must be > 0");
  if (keepalive_period_ms <= 0) return Refuse(why, "keepalive_period_ms must be > 0");
  return true;
}

SafeLightController::SafeLightController(std::unique_ptr<LightController> inner, LightSafetyOptions options)
    : LightController(inner->id()), inner_(std::move(inner)), options_(std::move(options)) {}

SafeLightController::~SafeLightController() {
  (void)Close();
  SafetyNet::Remove(this);
}

Status SafeLightController::DoOpen() {
  std::string why;
  if (!options_.IsValid(inner_->channel_count(), &why))
    return {StatusCode::kInvalidArgument, "light controller " + id() + ": safety limits: " + why};
  Status status = inner_->Open();
  if (!status.ok()) return status;
  {
    std::lock_guard lock(mutex_);
    channels_.assign(inner_->channel_count(), Channel{});
    current_ = LightPattern::AllOff(inner_->channel_count());
    last_command_ = last_keepalive_ = Clock::now();
    stopping_ = false;
    pending_report_.clear();
  }
  monitor_ = std::thread([this] { Monitor(); });
  SafetyNet::Add(this, [this] { (void)Close(); });
  return Status::Ok();
}

double SafeLightController::OnTimeInWindowMs(const Channel& channel, Clock::time_point now) const {
  const auto window_start = now - std::chrono::microseconds(static_cast<long>(options_.duty_window_ms * 1000));
  double total = 0;
  for (const auto& [begin, end] : channel.history)
    if (end > window_start) total += Ms(end - std::max(begin, window_start));
  if (channel.on) total += Ms(now - std::max(channel.on_since, window_start));
  return total;
}

std::string SafeLightController::Violation(int index, Clock::time_point now, bool switching_on) const {
  const ChannelLimits& limits = options_.For(index);
  const Channel& channel = channels_[index];
  const std::string name = "channel " + std::to_string(index) + ": ";
  if (limits.max_on_ms > 0 && channel.on && Ms(now - channel.on_since) >= limits.max_on_ms)
    return name + Fmt("on-time %.0f ms reached the limit of %.0f ms", Ms(now - channel.on_since), limits.max_on_ms);
  const double used = OnTimeInWindowMs(channel, now);
  const double allowed = limits.max_duty * options_.duty_window_ms;
  if (limits.max_duty < 1.0 && used >= allowed && (channel.on || switching_on))
    return name + Fmt("duty %.3f of the window reached the limit of %.3f", used / options_.duty_window_ms,
                      limits.max_duty);
  return {};
}

Status SafeLightController::ApplyLocked(const LightPattern& pattern, Clock::time_point now) {
  Status status = inner_->SetPattern(pattern);
  // Book-keep what was asked even on failure: the safe assumption is that it is lit.
  for (int i = 0; i < static_cast<int>(channels_.size()); ++i) {
    Channel& channel = channels_[i];
    const bool on = pattern.levels[i] > 0.0;
    if (on && !channel.on) channel.on_since = now;
    if (!on && channel.on) channel.history.emplace_back(channel.on_since, now);
    channel.on = on || (channel.on && !status.ok());
    const auto window_start = now - std::chrono::microseconds(static_cast<long>(options_.duty_window_ms * 1000));
    while (!channel.history.empty() && channel.history.front().second < window_start) channel.history.pop_front();
  }
  if (status.ok()) current_ = pattern;
  return status;
}

Status SafeLightController::DoSetPattern(const LightPattern& pattern) {
  std::lock_guard lock(mutex_);
  const auto now = Clock::now();
  last_command_ = now;
  std::string refused;
  LightPattern allowed = pattern;
  for (int i = 0; i < static_cast<int>(channels_.size()); ++i) {
    if (pattern.levels[i] <= 0.0) continue;
    std::string why = Violation(i, now, !channels_[i].on);
    if (why.empty()) continue;
    allowed.levels[i] = 0.0;
    if (refused.empty()) refused = why;
  }
  Status status = ApplyLocked(allowed, now);
  std::string report = pending_report_;
  pending_report_.clear();
  if (!refused.empty()) report = refused;
  if (!report.empty())
    return {StatusCode::kFailedPrecondition, "light controller " + id() + ": safety limit: " + report};
  return status;
}

void SafeLightController::Heartbeat() {
  std::lock_guard lock(mutex_);
  last_command_ = Clock::now();
}

std::vector<std::string> SafeLightController::cuts() const {
  std::lock_guard lock(mutex_);
  return cuts_;
}

void SafeLightController::Monitor() {
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    wake_.wait_for(lock, std::chrono::milliseconds(options_.monitor_period_ms));
    if (stopping_) break;
    const auto now = Clock::now();
    if (Ms(now - last_keepalive_) >= options_.keepalive_period_ms) {
      last_keepalive_ = now;
      // A link that no longer answers leaves the dead-man to switch the
      // outputs off; the next command reports it.
      Status alive = inner_->KeepAlive();
      if (!alive.ok()) pending_report_ = "keep-alive failed: " + alive.ToString();
    }
    LightPattern next = current_;
    std::string reason;
    if (options_.watchdog_ms > 0 && !current_.IsDark() && Ms(now - last_command_) >= options_.watchdog_ms) {
      next = LightPattern::AllOff(static_cast<int>(channels_.size()));
      reason = Fmt("watchdog: no command for %.0f ms (limit %.0f ms), all off", Ms(now - last_command_),
                   options_.watchdog_ms);
    } else {
      for (int i = 0; i < static_cast<int>(channels_.size()); ++i) {
        if (!channels_[i].on) continue;
        std::string why = Violation(i, now, false);
        if (why.empty()) continue;
        next.levels[i] = 0.0;
        if (reason.empty()) reason = why + ", cut";
      }
    }
    if (reason.empty()) continue;
    Status status = ApplyLocked(next, now);
    if (!status.ok()) {
      // The device did not take the cut: try everything off.
      status = ApplyLocked(LightPattern::AllOff(static_cast<int>(channels_.size())), now);
      reason += "; cut failed, all off: " + status.ToString();
    }
    cuts_.push_back(reason);
    pending_report_ = reason;
  }
}

Status SafeLightController::DoKeepAlive() {
  Heartbeat();
  std::lock_guard lock(mutex_);
  last_keepalive_ = Clock::now();
  return inner_->KeepAlive();
}

Result<LightPattern> SafeLightController::DoReadBack() {
  std::lock_guard lock(mutex_);
  return inner_->ReadBack();
}

Status SafeLightController::DoClose() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (monitor_.joinable()) monitor_.join();
  SafetyNet::Remove(this);
  std::lock_guard lock(mutex_);
  return inner_->Close();
}

}  // namespace photorig::drivers
