#pragma once
// A simulated gonioreflectometer axis (light arm, camera/detector arm or
// sample rotation stage) behind the Modbus drive profile
// (photorig/drivers/motion/modbus_drive.h): trapezoidal velocity profile,
// hardware limit switches, homing to 0, and injected motion faults counted
// by move command from 0:
//   stall_moves: the motor stops half way while the drive still reports busy
//                (an open-loop stepper losing steps);
//   overshoot_moves: the arm runs overshoot_deg past the target and stops there.

#include "photorig/sim/modbus/server.h"

#include <cstdint>
#include <mutex>
#include <set>
#include <string>

namespace photorig::sim {

struct SimArmOptions {
  std::string name = "arm";
  int base_address = 1000;
  double initial_position_deg = 7.5;   // where the arm happens to be at power-up (not homed)
  double hard_min_deg = -190.0;        // limit switches
  double hard_max_deg = 190.0;
  double homing_velocity_deg_s = 90.0;
  double max_velocity_deg_s = 360.0;
  double max_acceleration_deg_s2 = 2000.0;
  std::set<std::uint64_t> stall_moves;
  std::set<std::uint64_t> overshoot_moves;
  double overshoot_deg = 2.0;
};

class SimArm : public ModbusPeer {
 public:
  explicit SimArm(SimArmOptions options);

  void Advance(modbus_mapping_t* map, double now_s) override;
  void AfterWrite(modbus_mapping_t* map, double now_s) override;

  double position_deg() const;
  bool homed() const;
  std::uint64_t moves() const;

 private:
  struct Profile {
    double start_s = 0, from_deg = 0, to_deg = 0, velocity = 1, acceleration = 1;
    double stop_at_fraction = 1.0;  // < 1: stalls there
  };
  double ProfilePosition(double now_s, bool* done) const;
  void StartProfile(double now_s, double to_deg, double velocity, double acceleration, double stop_fraction);
  void Publish(modbus_mapping_t* map) const;

  SimArmOptions options_;
  mutable std::mutex mutex_;
  double position_deg_;
  bool busy_ = false, homing_ = false, homed_ = false;
  bool fault_ = false, limit_low_ = false, limit_high_ = false;
  std::uint16_t fault_code_ = 0;
  std::uint64_t moves_ = 0;
  Profile profile_;
};

}  // namespace photorig::sim
