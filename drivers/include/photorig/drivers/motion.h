#pragma once
// Motion interface for one rotary axis (a gonioreflectometer's light arm,
// camera/detector arm or sample rotation stage): an explicit state machine
//
//   Closed --Open--> Open --Home--> [Homing] --> Idle --MoveTo--> [Moving] --> Idle
//                     ^                                                      |
//                     +--ClearFault-- Fault <-- any failure while homing/moving
//
// Homing and Moving are transient: Home and MoveTo block until the drive has
// settled (or fail and leave the axis in Fault after stopping it). The public
// methods check transitions and soft limits, run the move-and-settle loop and
// detect stalls and overshoot; drivers implement the Do* hooks only. Close
// stops the drive first, from any state.

#include "photorig/drivers/device.h"
#include "photorig/drivers/status.h"

#include <string>

namespace photorig::drivers {

// An axis's frame on the rig, in rig degrees.
struct AxisLimits {
  double min_deg = -180.0;  // soft limits: a target outside is refused before anything moves
  double max_deg = 180.0;
  // Where homing leaves the axis: the rig angle of the drive's own zero. The
  // drive counts from its home switch; Motion adds this to every position it
  // reports and subtracts it from every target, so callers see rig angles.
  // Arms that share a circle need different homes (see Goniometer::HomeAll).
  double home_deg = 0.0;
  bool Contains(double position_deg) const { return position_deg >= min_deg && position_deg <= max_deg; }
};

struct MotionProfile {
  double velocity_deg_s = 30.0;
  double acceleration_deg_s2 = 120.0;
};

struct SettleOptions {
  double tolerance_deg = 0.05;       // |position - target| that counts as arrived
  int settle_ms = 30;                // must stay within tolerance this long
  int timeout_ms = 20000;            // for one move or homing run
  int poll_ms = 5;
  int stall_window_ms = 250;         // busy but moved less than stall_progress_deg in this window: stalled
  double stall_progress_deg = 0.01;
  double overshoot_deg = 0.5;        // past the target by more than this: overshoot fault

  bool IsValid(std::string* why) const;
};

// What the drive reports when polled.
struct AxisStatus {
  double position_deg = 0.0;
  bool busy = false;        // a move or homing run is in progress
  bool homed = false;
  bool fault = false;       // the drive's own fault flag
  bool limit_low = false;   // hardware limit switches
  bool limit_high = false;
  std::string fault_text;   // the drive's reason, if it gives one
};

class Motion : public Device {
 public:
  enum class State { kClosed, kOpen, kHoming, kIdle, kMoving, kFault };

  Motion(std::string id, AxisLimits limits, SettleOptions settle);
  // Implementations call Close() in their own destructor (the hooks are gone by the time this runs).
  virtual ~Motion();

  State state() const { return state_; }
  const AxisLimits& limits() const { return limits_; }
  const std::string& fault_reason() const { return fault_reason_; }

  Status Open();
  Status Home();
  Status MoveTo(double target_deg, const MotionProfile& profile = {});
  Status Stop();        // halts the drive; Homing/Moving/Idle -> Idle (Open if never homed)
  Status ClearFault();  // Fault -> Open: the axis must be homed again
  Result<AxisStatus> Poll();  // positions in rig degrees (see AxisLimits::home_deg)
  Status Close();       // from any state; stops the drive first; safe to call twice

 protected:
  virtual Status DoOpen() = 0;
  virtual Status DoStartHome() = 0;
  virtual Status DoStartMove(double target_deg, const MotionProfile& profile) = 0;
  virtual Result<AxisStatus> DoReadStatus() = 0;
  virtual Status DoStop() = 0;
  virtual Status DoClearFault() = 0;
  virtual Status DoClose() = 0;

 private:
  Status IllegalTransition(const char* action) const;
  Result<AxisStatus> ReadStatus();  // DoReadStatus in rig degrees
  // Stops the drive and enters Fault; returns the error naming the axis.
  Status EnterFault(StatusCode code, const std::string& reason);
  Status WaitSettled(double start_deg, double target_deg, bool homing);

  AxisLimits limits_;
  SettleOptions settle_;
  State state_ = State::kClosed;
  bool homed_ = false;
  std::string fault_reason_;
};

const char* MotionStateName(Motion::State state);

}  // namespace photorig::drivers
