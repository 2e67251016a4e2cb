#include "photorig/drivers/motion.h"

#include "photorig/drivers/internal/safety_net.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>

namespace photorig::drivers {
namespace {

using Clock = std::chrono::steady_clock;

double ElapsedMs(Clock::time_point since) {
  return std::chrono::duration<double, std::milli>(Clock::now() - since).count();
}

std::string Degrees(double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.3f deg", value);
  return text;
}

}  // namespace

bool SettleOptions::IsValid(std::string* why) const {
  if (!(tolerance_deg > 0)) return Refuse(why, "tolerance_deg must be > 0");
  if (settle_ms < 0 || poll_ms <= 0 || timeout_ms <= 0) return Refuse(why, "settle_ms >= 0, poll_ms > 0, timeout_ms > 0");
  if (stall_window_ms <= poll_ms) return Refuse(why, "stall_window_ms must exceed poll_ms");
  if (!(overshoot_deg >= tolerance_deg)) return Refuse(why, "overshoot_deg must be >= tolerance_deg");
  return true;
}

const char* MotionStateName(Motion::State state) {
  switch (state) {
    case Motion::State::kClosed: return "closed";
    case Motion::State::kOpen: return "open";
    case Motion::State::kHoming: return "homing";
    case Motion::State::kIdle: return "idle";
    case Motion::State::kMoving: return "moving";
    case Motion::State::kFault: return "fault";
  }
  return "?";
}

Motion::Motion(std::string id, AxisLimits limits, SettleOptions settle)
    : Device("axis", std::move(id)), limits_(limits), settle_(settle) {}

Motion::~Motion() { SafetyNet::Remove(this); }

Status Motion::IllegalTransition(const char* action) const {
  std::string state = MotionStateName(state_);
  if (state_ == State::kFault) state += " (" + fault_reason_ + "; clear the fault first)";
  return Device::IllegalTransition(action, state);
}

Status Motion::EnterFault(StatusCode code, const std::string& reason) {
  const Status stopped = DoStop();
  state_ = State::kFault;
  homed_ = false;  // after a fault the position is not trusted until homed again
  fault_reason_ = reason + (stopped.ok() ? "" : "; stop failed: " + stopped.message());
  return DeviceError(code, fault_reason_);
}

Status Motion::Open() {
  if (state_ != State::kClosed) return IllegalTransition("open");
  std::string why;
  if (!settle_.IsValid(&why)) return DeviceError(StatusCode::kInvalidArgument, why);
  if (!(limits_.min_deg < limits_.max_deg))
    return DeviceError(StatusCode::kInvalidArgument, "soft limits need min_deg < max_deg");
  if (!limits_.Contains(limits_.home_deg))
    return DeviceError(StatusCode::kInvalidArgument, "home " + Degrees(limits_.home_deg) +
                                                         " outside its soft limits [" + Degrees(limits_.min_deg) +
                                                         ", " + Degrees(limits_.max_deg) + "]");
  Status status = DoOpen();
  if (!status.ok()) return status;
  state_ = State::kOpen;
  homed_ = false;
  SafetyNet::Add(this, [this] { (void)Close(); });
  // Whatever a previous process left running, start stopped.
  status = DoStop();
  if (!status.ok()) (void)Close();
  return status;
}

Status Motion::Home() {
  if (state_ != State::kOpen && state_ != State::kIdle) return IllegalTransition("home");
  // Progress is measured from where the drive starts (a stall check against
  // the home itself would call a short run that ends there a stall).
  Result<AxisStatus> start = ReadStatus();
  if (!start.ok()) return EnterFault(start.status().code(), start.status().message());
  Status status = DoStartHome();
  if (!status.ok()) return EnterFault(status.code(), "homing not accepted: " + status.message());
  state_ = State::kHoming;
  return WaitSettled(start->position_deg, limits_.home_deg, true);
}

Status Motion::MoveTo(double target_deg, const MotionProfile& profile) {
  if (state_ != State::kIdle) return IllegalTransition(state_ == State::kOpen ? "move before homing" : "move");
  if (!limits_.Contains(target_deg))
    return DeviceError(StatusCode::kInvalidArgument, "target " + Degrees(target_deg) + " outside soft limits [" +
                                                         Degrees(limits_.min_deg) + ", " + Degrees(limits_.max_deg) +
                                                         "]");
  if (!(profile.velocity_deg_s > 0) || !(profile.acceleration_deg_s2 > 0))
    return DeviceError(StatusCode::kInvalidArgument, "velocity and acceleration must be > 0");
  Result<AxisStatus> start = ReadStatus();
  if (!start.ok()) return EnterFault(start.status().code(), start.status().message());
  Status status = DoStartMove(target_deg - limits_.home_deg, profile);
  if (!status.ok()) return EnterFault(status.code(), "move not accepted: " + status.message());
  state_ = State::kMoving;
  return WaitSettled(start->position_deg, target_deg, false);
}

Status Motion::WaitSettled(double start_deg, double target_deg, bool homing) {
  const auto begin = Clock::now();
  auto window_start = begin;
  auto settled_since = Clock::time_point{};
  bool in_tolerance = false;
  double window_position = start_deg;
  const double direction = target_deg >= start_deg ? 1.0 : -1.0;
  const char* what = homing ? "homing" : "move";
  for (;;) {
    Result<AxisStatus> polled = ReadStatus();
    if (!polled.ok()) return EnterFault(polled.status().code(), polled.status().message());
    const AxisStatus& s = polled.value();
    const double elapsed_ms = ElapsedMs(begin);
    if (s.fault)
      return EnterFault(StatusCode::kInternal, std::string("drive fault during ") + what + " at " +
                                                   Degrees(s.position_deg) +
                                                   (s.fault_text.empty() ? "" : ": " + s.fault_text));
    if (s.limit_low || s.limit_high)
      return EnterFault(StatusCode::kInternal, std::string("hit the ") + (s.limit_low ? "low" : "high") +
                                                   " limit switch at " + Degrees(s.position_deg));
    if (!homing && direction * (s.position_deg - target_deg) > settle_.overshoot_deg)
      return EnterFault(StatusCode::kInternal, "overshoot: at " + Degrees(s.position_deg) + " for target " +
                                                   Degrees(target_deg));
    if (s.busy) {
      // Stall: the drive claims to be moving but the position does not change.
      if (ElapsedMs(window_start) >= settle_.stall_window_ms) {
        if (std::abs(s.position_deg - window_position) < settle_.stall_progress_deg)
          return EnterFault(StatusCode::kInternal, std::string("stalled during ") + what + " at " +
                                                       Degrees(s.position_deg) + " (no progress in " +
                                                       std::to_string(settle_.stall_window_ms) + " ms)");
        window_start = Clock::now();
        window_position = s.position_deg;
      }
      in_tolerance = false;
    } else if (homing) {
      if (!s.homed) return EnterFault(StatusCode::kInternal, "homing ended without finding home");
      homed_ = true;
      state_ = State::kIdle;
      return Status::Ok();
    } else if (std::abs(s.position_deg - target_deg) <= settle_.tolerance_deg) {
      if (!in_tolerance) settled_since = Clock::now();
      in_tolerance = true;
      if (ElapsedMs(settled_since) >= settle_.settle_ms) {
        state_ = State::kIdle;
        return Status::Ok();
      }
    } else {
      return EnterFault(StatusCode::kInternal, "drive stopped at " + Degrees(s.position_deg) + ", target " +
                                                   Degrees(target_deg));
    }
    if (elapsed_ms > settle_.timeout_ms)
      return EnterFault(StatusCode::kTimeout, std::string(what) + " not settled within " +
                                                  std::to_string(settle_.timeout_ms) + " ms (at " +
                                                  Degrees(s.position_deg) + ")");
    std::this_thread::sleep_for(std::chrono::milliseconds(settle_.poll_ms));
  }
}

Status Motion::Stop() {
  if (state_ == State::kClosed) return IllegalTransition("stop");
  Status status = DoStop();
  if (state_ != State::kFault) state_ = homed_ ? State::kIdle : State::kOpen;
  return status;
}

Status Motion::ClearFault() {
  if (state_ != State::kFault) return IllegalTransition("clear a fault");
  Status status = DoClearFault();
  if (!status.ok()) return status;
  state_ = State::kOpen;
  fault_reason_.clear();
  return Status::Ok();
}

Result<AxisStatus> Motion::Poll() {
  if (state_ == State::kClosed) return IllegalTransition("poll");
  return ReadStatus();
}

Result<AxisStatus> Motion::ReadStatus() {
  Result<AxisStatus> status = DoReadStatus();
  if (status.ok()) status->position_deg += limits_.home_deg;
  return status;
}

Status Motion::Close() {
  if (state_ == State::kClosed) return Status::Ok();
  Status stopped = DoStop();
  Status closed = DoClose();
  state_ = State::kClosed;
  homed_ = false;
  SafetyNet::Remove(this);
  return stopped.ok() ? closed : stopped;
}

}  // namespace photorig::drivers
