#pragma once
// An output that fires a camera's hardware trigger input: a GPIO line, a
// strobe output of an LED controller, or the simulated rig's wire. The
// sequencer fires it once per frame after the lights have settled, then waits
// for the frame with a timeout; a camera armed for a hardware trigger
// (CameraSettings::trigger = kHardware) ignores software triggers.
//
//   Closed --Open--> Open --Fire--> Open --Close--> Closed
//
// The public methods check the transition and the pulse width, then call the
// implementation's Do* hooks; an illegal transition returns
// kFailedPrecondition and changes nothing. Close leaves the output
// deasserted, from any state, and is safe to call twice. An open output is
// registered with the SafetyNet, so it is released at exit as well.

#include "photorig/drivers/device.h"
#include "photorig/drivers/status.h"

#include <chrono>
#include <string>

namespace photorig::drivers {

class TriggerOutput : public Device {
 public:
  enum class State { kClosed, kOpen };

  explicit TriggerOutput(std::string id) : Device("trigger", std::move(id)) {}
  // Implementations call Close() in their own destructor (the hooks are gone by the time this runs).
  virtual ~TriggerOutput();

  State state() const { return state_; }

  // Claims the output, deasserted.
  Status Open();
  // Asserts the output for `width` (> 0), then deasserts it. Only while open.
  Status Fire(std::chrono::microseconds width);
  Status Close();

 protected:
  virtual Status DoOpen() = 0;
  // Called with width > 0; must end with the output deasserted, even on failure where it can.
  virtual Status DoFire(std::chrono::microseconds width) = 0;
  // Deasserts the output and releases it.
  virtual Status DoClose() = 0;

 private:
  Status IllegalTransition(const char* action) const;

  State state_ = State::kClosed;
};

const char* TriggerOutputStateName(TriggerOutput::State state);

}  // namespace photorig::drivers
