#pragma once
// An output that fires a camera's hardware trigger input: a GPIO line, a
// strobe output of an LED controller, or the simulated rig's wire. The
// sequencer fires it once per frame after the lights have settled, then waits
// for the frame with a timeout; a camera armed for a hardware trigger
// (CameraSettings::trigger = kHardware) ignores software triggers.
//
//   Closed --Open--> Open --Fire--> Open --Close--> Closed
//
// Close leaves the output deasserted, from any state.

#include "photorig/drivers/status.h"

#include <chrono>
#include <string>

namespace photorig::drivers {

class TriggerOutput {
 public:
  virtual ~TriggerOutput() = default;
  virtual const std::string& id() const = 0;
  virtual Status Open() = 0;
  // Asserts the output for `width`, then deasserts it. Only while open.
  virtual Status Fire(std::chrono::microseconds width) = 0;
  virtual Status Close() = 0;
  virtual bool is_open() const = 0;
};

}  // namespace photorig::drivers
