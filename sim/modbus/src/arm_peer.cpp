#include "photorig/sim/modbus/internal/arm_peer.h"

#include "photorig/drivers/motion/modbus_drive.h"

#include <modbus/modbus.h>

#include <algorithm>
#include <cmath>

namespace photorig::sim {

namespace dp = drivers::drive_profile;

SimArm::SimArm(SimArmOptions options) : options_(std::move(options)), position_deg_(options_.initial_position_deg) {}

double SimArm::position_deg() const {
  std::lock_guard lock(mutex_);
  return position_deg_;
}

bool SimArm::homed() const {
  std::lock_guard lock(mutex_);
  return homed_;
}

std::uint64_t SimArm::moves() const {
  std::lock_guard lock(mutex_);
  return moves_;
}

void SimArm::StartProfile(double now_s, double to_deg, double velocity, double acceleration, double stop_fraction) {
  profile_ = {now_s, position_deg_, to_deg, std::min(velocity, options_.max_velocity_deg_s),
              std::min(acceleration, options_.max_acceleration_deg_s2), stop_fraction};
  busy_ = true;
}

// Distance along a trapezoidal (or triangular) velocity profile.
double SimArm::ProfilePosition(double now_s, bool* done) const {
  const Profile& p = profile_;
  const double distance = std::abs(p.to_deg - p.from_deg);
  const double sign = p.to_deg >= p.from_deg ? 1.0 : -1.0;
  const double t = std::max(0.0, now_s - p.start_s);
  double ramp_s = p.velocity / p.acceleration;
  double cruise_s = 0.0;
  double peak = p.velocity;
  if (p.acceleration * ramp_s * ramp_s > distance) {  // never reaches cruise speed
    ramp_s = std::sqrt(distance / p.acceleration);
    peak = p.acceleration * ramp_s;
  } else {
    cruise_s = (distance - p.acceleration * ramp_s * ramp_s) / p.velocity;
  }
  double s;
  if (t < ramp_s) s = 0.5 * p.acceleration * t * t;
  else if (t < ramp_s + cruise_s) s = 0.5 * peak * ramp_s + peak * (t - ramp_s);
  else if (t < 2 * ramp_s + cruise_s) {
    const double u = 2 * ramp_s + cruise_s - t;
    s = distance - 0.5 * p.acceleration * u * u;
  } else s = distance;
  const double stall_at = distance * p.stop_at_fraction;
  *done = s >= distance && p.stop_at_fraction >= 1.0;
  return p.from_deg + sign * std::min(s, stall_at);
}

void SimArm::Advance(modbus_mapping_t* map, double now_s) {
  std::lock_guard lock(mutex_);
  if (busy_) {
    bool done = false;
    position_deg_ = ProfilePosition(now_s, &done);
    if (position_deg_ <= options_.hard_min_deg || position_deg_ >= options_.hard_max_deg) {
      limit_low_ = position_deg_ <= options_.hard_min_deg;
      limit_high_ = !limit_low_;
      position_deg_ = std::clamp(position_deg_, options_.hard_min_deg, options_.hard_max_deg);
      busy_ = homing_ = false;
      fault_ = true;
      fault_code_ = dp::kLimitSwitch;
    } else if (done) {
      busy_ = false;
      if (homing_) homed_ = true;
      homing_ = false;
    }
  }
  Publish(map);
}

void SimArm::Publish(modbus_mapping_t* map) const {
  std::uint16_t* r = map->tab_registers + options_.base_address;
  r[dp::kStatus] = static_cast<std::uint16_t>((busy_ ? dp::kBusy : 0) | (homed_ ? dp::kHomed : 0) |
                                              (fault_ ? dp::kFault : 0) | (limit_low_ ? dp::kLimitLow : 0) |
                                              (limit_high_ ? dp::kLimitHigh : 0));
  dp::EncodeMillidegrees(position_deg_, r + dp::kPosition);
  r[dp::kFaultCode] = fault_code_;
}

void SimArm::AfterWrite(modbus_mapping_t* map, double now_s) {
  std::lock_guard lock(mutex_);
  std::uint16_t* r = map->tab_registers + options_.base_address;
  const std::uint16_t command = r[dp::kCommand];
  r[dp::kCommand] = dp::kNone;
  switch (command) {
    case dp::kMove: {
      if (fault_) break;  // a faulted drive ignores motion commands
      const double target = dp::DecodeMillidegrees(r + dp::kTarget);
      const double sign = target >= position_deg_ ? 1.0 : -1.0;
      const std::uint64_t index = moves_++;
      const double overshoot = options_.overshoot_moves.count(index) ? sign * options_.overshoot_deg : 0.0;
      StartProfile(now_s, target + overshoot, std::max<int>(1, r[dp::kVelocity]) / 10.0,
                   std::max<int>(1, r[dp::kAcceleration]) / 10.0, options_.stall_moves.count(index) ? 0.5 : 1.0);
      homing_ = false;
      break;
    }
    case dp::kHome:
      if (fault_) break;
      StartProfile(now_s, 0.0, options_.homing_velocity_deg_s, options_.max_acceleration_deg_s2, 1.0);
      homing_ = true;
      homed_ = false;
      break;
    case dp::kStop:
      busy_ = homing_ = false;
      break;
    case dp::kClearFault:
      fault_ = limit_low_ = limit_high_ = false;
      fault_code_ = dp::kNoFault;
      homed_ = false;
      break;
    default: break;
  }
  Publish(map);
}

}  // namespace photorig::sim
