#pragma once
// A Modbus server (libmodbus) that simulated devices sit behind: the LED
// controller bound to a sim::World and the gonioreflectometer arms. It serves
// Modbus TCP on a loopback port (0 = pick a free one) or Modbus RTU on a
// pseudo-terminal pair (clients open rtu_path()), on its own thread, and
// stops cleanly. Faults are injected per request, counted from 0 over the
// server's life: an exception reply, a dropped connection (TCP) or a missing
// reply (RTU), or an exception for any request touching given addresses.

#include "photorig/drivers/status.h"

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

typedef struct _modbus modbus_t;
typedef struct _modbus_mapping_t modbus_mapping_t;

namespace photorig::sim {

struct ModbusServerFaults {
  std::set<std::uint64_t> exception_at;   // reply "server device failure" to these requests
  std::set<std::uint64_t> disconnect_at;  // drop the connection (TCP) / stay silent (RTU)
  std::set<int> exception_addresses;      // "illegal data address" for requests covering these
};

// One simulated device behind the server. Calls come from the server thread
// with the register map locked.
class ModbusPeer {
 public:
  virtual ~ModbusPeer() = default;
  // Before every reply: advance the device to `now_s` and refresh what it reports.
  virtual void Advance(modbus_mapping_t* map, double now_s) = 0;
  // After a write request was applied to the map.
  virtual void AfterWrite(modbus_mapping_t* map, double now_s) = 0;
  // Every ~10 ms whether or not a request came: timeouts that run on the
  // device's own clock.
  virtual void Tick(modbus_mapping_t*, double) {}
};

struct ModbusServerOptions {
  int coils = 2048;
  int holding_registers = 4096;
  int unit_id = 1;       // RTU answers only this address; TCP answers any
  int rtu_baud = 115200;
  ModbusServerFaults faults;
};

class SimModbusServer {
 public:
  explicit SimModbusServer(ModbusServerOptions options = {});
  ~SimModbusServer();
  SimModbusServer(const SimModbusServer&) = delete;
  SimModbusServer& operator=(const SimModbusServer&) = delete;

  // Peers must be added before Start.
  void AddPeer(std::shared_ptr<ModbusPeer> peer);
  Status StartTcp(const std::string& host = "127.0.0.1", int port = 0);
  Status StartRtu();
  void Stop();  // joins the thread; safe to call twice

  int port() const { return port_; }
  const std::string& rtu_path() const { return rtu_path_; }
  std::uint64_t requests() const { return requests_.load(); }
  // Drops every TCP client now (a controller power-cycle, a cable pulled).
  void DropClients() { drop_clients_.store(true); }

 private:
  // Maps the coils and registers and starts serving on the context just made.
  Status Launch(bool rtu);
  void Serve();
  // Handles one received request on `fd`; false when the connection must close.
  bool Handle(const std::uint8_t* request, int length);

  ModbusServerOptions options_;
  std::vector<std::shared_ptr<ModbusPeer>> peers_;
  modbus_t* ctx_ = nullptr;
  modbus_mapping_t* map_ = nullptr;
  std::mutex map_mutex_;
  int listen_fd_ = -1;
  int pty_master_ = -1, pty_slave_ = -1;
  int port_ = 0;
  std::string rtu_path_;
  bool rtu_ = false;
  std::atomic<bool> stop_{false};
  std::atomic<bool> drop_clients_{false};
  std::atomic<std::uint64_t> requests_{0};
  std::thread thread_;
};

}  // namespace photorig::sim
