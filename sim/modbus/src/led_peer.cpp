#include "photorig/sim/modbus/led_peer.h"

#include <modbus/modbus.h>

#include <algorithm>
#include <stdexcept>

namespace photorig::sim {

SimModbusLedController::SimModbusLedController(drivers::ModbusLightMap map, std::shared_ptr<World> world,
                                               std::set<int> stuck_off)
    : map_(map), world_(std::move(world)), stuck_off_(std::move(stuck_off)) {
  std::string why;
  if (!map_.IsValid(&why)) throw std::invalid_argument("simulated Modbus LED controller: " + why);
  const int leds = static_cast<int>(world_->config().lights.size());
  if (map_.channels != leds)
    throw std::invalid_argument("simulated Modbus LED controller: map has " + std::to_string(map_.channels) +
                                " channels, the world " + std::to_string(leds) + " LEDs");
  for (int channel : world_->config().light_faults.stuck_off_channels) stuck_off_.insert(channel);
}

void SimModbusLedController::Advance(modbus_mapping_t*, double now_s) { last_request_s_ = now_s; }

void SimModbusLedController::Tick(modbus_mapping_t* m, double now_s) {
  if (map_.watchdog_address < 0 || map_.watchdog_address >= m->nb_registers || last_request_s_ < 0) return;
  const int timeout_ms = m->tab_registers[map_.watchdog_address];
  if (timeout_ms == 0 || (now_s - last_request_s_) * 1000.0 < timeout_ms) return;
  last_request_s_ = -1.0;  // tripped: quiet until the next request
  const int n = map_.channels;
  bool lit = false;
  for (double level : world_->levels()) lit = lit || level > 0.0;
  if (!lit) return;
  if (map_.on_off == drivers::ModbusLightMap::Switch::kCoils && map_.on_off_address + n <= m->nb_bits)
    std::fill_n(m->tab_bits + map_.on_off_address, n, 0);
  if (map_.on_off == drivers::ModbusLightMap::Switch::kBitmask &&
      map_.on_off_address + map_.bitmask_registers() <= m->nb_registers)
    std::fill_n(m->tab_registers + map_.on_off_address, map_.bitmask_registers(), 0);
  if (map_.intensity && map_.intensity_address + n <= m->nb_registers)
    std::fill_n(m->tab_registers + map_.intensity_address, n, 0);
  world_->SetLevels(std::vector<double>(n, 0.0));
  ++trips_;
}

void SimModbusLedController::AfterWrite(modbus_mapping_t* m, double) {
  ++writes_;
  const int n = map_.channels;
  const bool coils_fit = map_.on_off != drivers::ModbusLightMap::Switch::kCoils || map_.on_off_address + n <= m->nb_bits;
  const bool mask_fit = map_.on_off != drivers::ModbusLightMap::Switch::kBitmask ||
                        map_.on_off_address + map_.bitmask_registers() <= m->nb_registers;
  const bool intensity_fit = !map_.intensity || map_.intensity_address + n <= m->nb_registers;
  if (!coils_fit || !mask_fit || !intensity_fit) return;  // the server answered "illegal address" already
  std::vector<double> levels(n, 0.0);
  for (int i = 0; i < n; ++i) {
    const bool stuck = stuck_off_.count(i) > 0;
    bool on = true;
    if (map_.on_off == drivers::ModbusLightMap::Switch::kCoils) {
      std::uint8_t& coil = m->tab_bits[map_.on_off_address + i];
      if (stuck) coil = 0;
      on = coil != 0;
    } else if (map_.on_off == drivers::ModbusLightMap::Switch::kBitmask) {
      std::uint16_t& mask = m->tab_registers[map_.on_off_address + i / 16];
      if (stuck) mask &= static_cast<std::uint16_t>(~(1u << (i % 16)));
      on = (mask >> (i % 16)) & 1u;
    }
    double level = 1.0;
    if (map_.intensity) {
      std::uint16_t& value = m->tab_registers[map_.intensity_address + i];
      if (stuck) value = 0;
      level = std::min(1.0, value / static_cast<double>(map_.full_scale));
    }
    levels[i] = on && !stuck ? level : 0.0;
  }
  world_->SetLevels(std::move(levels));
}

}  // namespace photorig::sim
