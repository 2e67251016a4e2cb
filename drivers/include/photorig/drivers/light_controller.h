#pragma once
// Light controller interface (LED dome over GPIO, Modbus or USB relays).
//
// Lifecycle: Closed --Open--> Open --Close--> Closed. Every pattern change
// goes through SetPattern; AllOff is always allowed while open, and Close
// switches every channel off before releasing the device, so an owner that
// closes on every exit path leaves the dome dark.

#include "photorig/drivers/device.h"
#include "photorig/drivers/status.h"

#include <string>
#include <vector>

namespace photorig::drivers {

// Relative drive level per channel in [0, 1]; 0 = off.
struct LightPattern {
  std::vector<double> levels;

  static LightPattern AllOff(int channels) { return {std::vector<double>(channels, 0.0)}; }
  static LightPattern Single(int channels, int channel, double level) {
    LightPattern pattern = AllOff(channels);
    pattern.levels.at(channel) = level;
    return pattern;
  }
  bool IsDark() const {
    for (double level : levels)
      if (level != 0.0) return false;
    return true;
  }
};

class LightController : public Device {
 public:
  enum class State { kClosed, kOpen };

  explicit LightController(std::string id) : Device("light controller", std::move(id)) {}
  virtual ~LightController() = default;

  State state() const { return state_; }
  virtual int channel_count() const = 0;

  Status Open();
  Status SetPattern(const LightPattern& pattern);
  Status AllOff();
  Result<LightPattern> ReadBack();
  Status Close();  // switches everything off first; safe to call twice
  // Tells the device its owner is alive. A controller with a hardware
  // dead-man (a watchdog that switches every output off when its link goes
  // quiet, armed at Open) is reset by it; for the others it does nothing.
  // Owners call it more often than the dead-man's timeout while open.
  Status KeepAlive();

 protected:
  virtual Status DoOpen() = 0;
  virtual Status DoSetPattern(const LightPattern& pattern) = 0;
  virtual Result<LightPattern> DoReadBack() = 0;
  virtual Status DoClose() = 0;
  virtual Status DoKeepAlive() { return Status::Ok(); }

 private:
  State state_ = State::kClosed;
};

}  // namespace photorig::drivers
