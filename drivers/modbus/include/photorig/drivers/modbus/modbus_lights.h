#pragma once
// LED controller over Modbus TCP or RTU. The register map comes from the rig
// YAML (see docs/lights-and-motion.md); the simulated controller in
// sim/modbus serves the same ModbusLightMap, so both ends agree by design.
//
// A channel's light output is
//   on(i) * (intensity registers ? register(i) / full_scale : 1)
// where on(i) is its coil, its bit in a bitmask holding register, or always
// true when the map has no on/off switch. SetPattern writes intensities first
// (one write-multiple), then the switches (one write-multiple), then reads
// both back and fails if the device disagrees (e.g. a stuck output).
//
// Hardware dead-man: with `watchdog_address` set, Open writes
// `watchdog_timeout_ms` to that holding register, arming the controller's
// communication-loss timeout (every output off when no request arrives for
// that long), and KeepAlive reads it back as the request that resets it. The
// SafeLightController in front keeps it alive while the process lives, so a
// process killed mid-exposure leaves the dome dark within the timeout.

#include "photorig/drivers/light_controller.h"
#include "photorig/drivers/modbus/modbus_link.h"

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace photorig::drivers {

struct ModbusLightMap {
  enum class Switch { kCoils, kBitmask, kNone };
  int channels = 0;
  Switch on_off = Switch::kCoils;
  int on_off_address = 0;          // first coil, or first bitmask holding register (16 channels each, LSB first)
  bool intensity = false;          // one holding register per channel
  int intensity_address = 100;     // first intensity register
  int full_scale = 1000;           // register value for level 1.0
  int watchdog_address = -1;       // holding register of the communication-loss timeout; -1 = none
  int watchdog_timeout_ms = 2000;  // written there at Open, in ms (1000..65535)

  bool IsValid(std::string* why) const;
  int bitmask_registers() const { return (channels + 15) / 16; }
  // What the device does with a pattern: levels quantised to the map.
  LightPattern Quantise(const LightPattern& pattern) const;
  std::uint16_t IntensityValue(double level) const;
  const char* SwitchName() const;
};

// Parses "coils" | "bitmask" | "none".
bool ParseModbusSwitch(const std::string& text, ModbusLightMap::Switch* out);

class ModbusLightController : public LightController {
 public:
  ModbusLightController(std::string id, ModbusLinkOptions link, ModbusLightMap map, bool verify = true);
  int channel_count() const override { return map_.channels; }
  const ModbusLink& link() const { return link_; }

 protected:
  Status DoOpen() override;
  Status DoSetPattern(const LightPattern& pattern) override;
  Result<LightPattern> DoReadBack() override;
  Status DoClose() override;
  Status DoKeepAlive() override;

 private:
  ModbusLightMap map_;
  ModbusLink link_;
  bool verify_;
};

}  // namespace photorig::drivers
