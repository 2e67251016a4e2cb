#pragma once
// A Modbus TCP or RTU connection to one unit, with the error handling every
// Modbus device on the rig needs: response and byte timeouts, retries with
// exponential backoff, reconnect after a dropped link, and errors that name
// the device, the request and the register range.
//
// Modbus exception replies (illegal address, device failure, ...) are the
// device's answer, not a transport fault: they are never retried.

#include "photorig/drivers/status.h"

#include <cstdint>
#include <string>
#include <vector>

typedef struct _modbus modbus_t;

namespace photorig::drivers {

struct ModbusLinkOptions {
  enum class Transport { kTcp, kRtu };
  Transport transport = Transport::kTcp;
  // TCP
  std::string host = "127.0.0.1";
  int port = 502;
  // RTU
  std::string serial_device;  // e.g. /dev/ttyUSB0
  int baud = 19200;
  char parity = 'N';          // 'N', 'E' or 'O'
  int data_bits = 8;
  int stop_bits = 1;

  int unit_id = 1;                 // Modbus slave address; TCP gateways route on it
  int response_timeout_ms = 200;   // whole reply
  int byte_timeout_ms = 50;        // gap between bytes of one reply
  int retries = 3;                 // extra attempts after a transport failure
  int retry_backoff_ms = 10;       // doubles after every failed attempt

  bool IsValid(std::string* why) const;
  std::string Describe() const;  // "tcp 127.0.0.1:502 unit 1"
};

class ModbusLink {
 public:
  // `device` names the owner in every error ("light controller dome0").
  ModbusLink(std::string device, ModbusLinkOptions options);
  ~ModbusLink();
  ModbusLink(const ModbusLink&) = delete;
  ModbusLink& operator=(const ModbusLink&) = delete;

  Status Connect();
  void Disconnect();
  bool connected() const { return ctx_ != nullptr && connected_; }
  const ModbusLinkOptions& options() const { return options_; }
  // Requests issued (attempts, including retries) since construction.
  std::uint64_t requests() const { return requests_; }

  // Each call splits into as few requests as the protocol limits allow.
  Status WriteCoils(int address, const std::vector<std::uint8_t>& bits);
  Status WriteRegisters(int address, const std::vector<std::uint16_t>& values);
  Result<std::vector<std::uint8_t>> ReadCoils(int address, int count);
  Result<std::vector<std::uint16_t>> ReadRegisters(int address, int count);

 private:
  enum class Op { kWriteCoils, kWriteRegisters, kReadCoils, kReadRegisters };
  Status Transfer(Op op, int address, int count, void* data);
  Status Fail(StatusCode code, const std::string& what) const;

  std::string device_;
  ModbusLinkOptions options_;
  modbus_t* ctx_ = nullptr;
  bool connected_ = false;
  std::uint64_t requests_ = 0;
};

}  // namespace photorig::drivers
