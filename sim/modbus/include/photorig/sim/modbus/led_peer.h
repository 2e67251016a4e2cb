#pragma once
// The simulated Modbus LED controller: serves a drivers::ModbusLightMap and
// drives a sim::World's LED levels from it, so a SimCamera sees what the
// Modbus client commanded. Stuck-off channels (its own list plus the World's
// LightFaults::stuck_off_channels) never light, and their coils / bits /
// intensity registers read back as off, as a controller with a dead output
// stage reports it.
//
// With the map's watchdog register set to a nonzero timeout (ms), the
// controller switches every output off (coils, bits, intensities and the
// World's levels) when no request has arrived for that long, as a real
// controller's communication-loss timeout does; trips() counts it.

#include "photorig/drivers/modbus/modbus_lights.h"
#include "photorig/sim/modbus/server.h"
#include "photorig/sim/world.h"

#include <atomic>
#include <memory>
#include <set>

namespace photorig::sim {

class SimModbusLedController : public ModbusPeer {
 public:
  // Throws std::invalid_argument if the map is invalid or its channel count
  // differs from the World's LEDs.
  SimModbusLedController(drivers::ModbusLightMap map, std::shared_ptr<World> world, std::set<int> stuck_off = {});

  void Advance(modbus_mapping_t* map, double now_s) override;
  void AfterWrite(modbus_mapping_t* map, double now_s) override;
  void Tick(modbus_mapping_t* map, double now_s) override;
  std::uint64_t writes() const { return writes_; }
  int trips() const { return trips_; }

 private:
  drivers::ModbusLightMap map_;
  std::shared_ptr<World> world_;
  std::set<int> stuck_off_;
  std::uint64_t writes_ = 0;
  double last_request_s_ = -1.0;  // < 0: none yet (the timeout runs from the first request)
  std::atomic<int> trips_{0};
};

}  // namespace photorig::sim
