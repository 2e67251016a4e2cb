#include "photorig/drivers/modbus/modbus_lights.h"

#include <algorithm>
#include <cmath>

namespace photorig::drivers {

bool ModbusLightMap::IsValid(std::string* why) const {
  if (channels <= 0) return Refuse(why, "the map needs at least one channel");
  if (on_off == Switch::kNone && !intensity) return Refuse(why, "the map needs coils, a bitmask or intensity registers");
  if (on_off_address < 0 || on_off_address > 65535) return Refuse(why, "on/off address must be within [0, 65535]");
  if (intensity && (intensity_address < 0 || intensity_address + channels > 65536))
    return Refuse(why, "intensity registers must lie within [0, 65535]");
  if (intensity && (full_scale < 1 || full_scale > 65535)) return Refuse(why, "full scale must be within [1, 65535]");
  if (watchdog_address >= 0) {
    if (watchdog_address > 65535) return Refuse(why, "watchdog address must be within [0, 65535]");
    if (watchdog_timeout_ms < 1000 || watchdog_timeout_ms > 65535)
      return Refuse(why, "watchdog timeout must be within [1000, 65535] ms");
    const bool in_intensity = intensity && watchdog_address >= intensity_address &&
                              watchdog_address < intensity_address + channels;
    const bool in_mask = on_off == Switch::kBitmask && watchdog_address >= on_off_address &&
                         watchdog_address < on_off_address + bitmask_registers();
    if (in_intensity || in_mask) return Refuse(why, "watchdog register overlaps the LED registers");
  }
  if (on_off == Switch::kBitmask && intensity) {
    const int mask_end = on_off_address + bitmask_registers();
    if (on_off_address < intensity_address + channels && intensity_address < mask_end)
      return Refuse(why, "bitmask and intensity registers overlap");
  }
  return true;
}

const char* ModbusLightMap::SwitchName() const {
  switch (on_off) {
    case Switch::kCoils: return "coils";
    case Switch::kBitmask: return "bitmask";
    case Switch::kNone: return "none";
  }
  return "?";
}

bool ParseModbusSwitch(const std::string& text, ModbusLightMap::Switch* out) {
  if (text == "coils") *out = ModbusLightMap::Switch::kCoils;
  else if (text == "bitmask") *out = ModbusLightMap::Switch::kBitmask;
  else if (text == "none") *out = ModbusLightMap::Switch::kNone;
  else return false;
  return true;
}

std::uint16_t ModbusLightMap::IntensityValue(double level) const {
  return static_cast<std::uint16_t>(std::lround(std::clamp(level, 0.0, 1.0) * full_scale));
}

LightPattern ModbusLightMap::Quantise(const LightPattern& pattern) const {
  LightPattern out = pattern;
  for (double& level : out.levels) {
    if (intensity) level = IntensityValue(level) / static_cast<double>(full_scale);
    else level = level > 0.0 ? 1.0 : 0.0;
  }
  return out;
}

ModbusLightController::ModbusLightController(std::string id, ModbusLinkOptions link, ModbusLightMap map, bool verify)
    : LightController(id), map_(map), link_("light controller " + id, std::move(link)), verify_(verify) {}

Status ModbusLightController::DoOpen() {
  std::string why;
  if (!map_.IsValid(&why)) return {StatusCode::kInvalidArgument, "light controller " + id() + ": " + why};
  Status connected = link_.Connect();
  if (!connected.ok() || map_.watchdog_address < 0) return connected;
  return link_.WriteRegisters(map_.watchdog_address, {static_cast<std::uint16_t>(map_.watchdog_timeout_ms)});
}

Status ModbusLightController::DoKeepAlive() {
  if (map_.watchdog_address < 0) return Status::Ok();
  return link_.ReadRegisters(map_.watchdog_address, 1).status();
}

Status ModbusLightController::DoSetPattern(const LightPattern& pattern) {
  const int n = map_.channels;
  if (map_.intensity) {
    std::vector<std::uint16_t> values(n);
    for (int i = 0; i < n; ++i) values[i] = map_.IntensityValue(pattern.levels[i]);
    Status status = link_.WriteRegisters(map_.intensity_address, values);
    if (!status.ok()) return status;
  }
  if (map_.on_off == ModbusLightMap::Switch::kCoils) {
    std::vector<std::uint8_t> bits(n);
    for (int i = 0; i < n; ++i) bits[i] = pattern.levels[i] > 0.0 ? 1 : 0;
    Status status = link_.WriteCoils(map_.on_off_address, bits);
    if (!status.ok()) return status;
  } else if (map_.on_off == ModbusLightMap::Switch::kBitmask) {
    std::vector<std::uint16_t> masks(map_.bitmask_registers(), 0);
    for (int i = 0; i < n; ++i)
      if (pattern.levels[i] > 0.0) masks[i / 16] |= static_cast<std::uint16_t>(1u << (i % 16));
    Status status = link_.WriteRegisters(map_.on_off_address, masks);
    if (!status.ok()) return status;
  }
  if (!verify_) return Status::Ok();
  Result<LightPattern> actual = DoReadBack();
  if (!actual.ok()) return actual.status();
  const LightPattern expected = map_.Quantise(pattern);
  for (int i = 0; i < n; ++i) {
    if (std::abs(actual->levels[i] - expected.levels[i]) > 0.5 / map_.full_scale) {
      const bool switch_wrong = (actual->levels[i] > 0.0) != (expected.levels[i] > 0.0);
      const std::string where = switch_wrong && map_.on_off != ModbusLightMap::Switch::kNone
                                    ? std::string(map_.on_off == ModbusLightMap::Switch::kCoils ? "coil " : "bitmask register ") +
                                          std::to_string(map_.on_off == ModbusLightMap::Switch::kCoils
                                                             ? map_.on_off_address + i
                                                             : map_.on_off_address + i / 16)
                                    : "intensity register " + std::to_string(map_.intensity_address + i);
      return {StatusCode::kDataLoss, "light controller " + id() + " (" + link_.options().Describe() + "): channel " +
                                         std::to_string(i) + " reads back " + std::to_string(actual->levels[i]) +
                                         " after writing " + std::to_string(expected.levels[i]) + " (" + where + ")"};
    }
  }
  return Status::Ok();
}

Result<LightPattern> ModbusLightController::DoReadBack() {
  const int n = map_.channels;
  LightPattern pattern = LightPattern::AllOff(n);
  std::vector<bool> on(n, true);
  if (map_.on_off == ModbusLightMap::Switch::kCoils) {
    auto bits = link_.ReadCoils(map_.on_off_address, n);
    if (!bits.ok()) return bits.status();
    for (int i = 0; i < n; ++i) on[i] = bits.value()[i] != 0;
  } else if (map_.on_off == ModbusLightMap::Switch::kBitmask) {
    auto masks = link_.ReadRegisters(map_.on_off_address, map_.bitmask_registers());
    if (!masks.ok()) return masks.status();
    for (int i = 0; i < n; ++i) on[i] = (masks.value()[i / 16] >> (i % 16)) & 1u;
  }
  std::vector<std::uint16_t> values;
  if (map_.intensity) {
    auto read = link_.ReadRegisters(map_.intensity_address, n);
    if (!read.ok()) return read.status();
    values = std::move(read.value());
  }
  for (int i = 0; i < n; ++i) {
    const double level = map_.intensity ? std::min(1.0, values[i] / static_cast<double>(map_.full_scale)) : 1.0;
    pattern.levels[i] = on[i] ? level : 0.0;
  }
  return pattern;
}

Status ModbusLightController::DoClose() {
  link_.Disconnect();
  return Status::Ok();
}

}  // namespace photorig::drivers
