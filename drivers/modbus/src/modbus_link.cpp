#include "photorig/drivers/modbus/modbus_link.h"

#include <modbus/modbus.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <thread>

namespace photorig::drivers {
namespace {

const char* OpName(int op) {
  static const char* names[] = {"write coils", "write registers", "read coils", "read registers"};
  return names[op];
}

bool IsException(int error) { return error > MODBUS_ENOBASE && error <= EMBXGTAR; }

void SetTimeout(modbus_t* ctx, int timeout_ms, int (*set)(modbus_t*, uint32_t, uint32_t)) {
  set(ctx, static_cast<uint32_t>(timeout_ms / 1000), static_cast<uint32_t>((timeout_ms % 1000) * 1000));
}

// Moves `count` items between `items` and the device from `address` on,
// through transfer(address, n, data), in pieces of at most `most` items: one
// libmodbus request carries no more. Stops at the first failure.
template <typename T, typename Transfer>
Status InPieces(int address, T* items, int count, int most, const Transfer& transfer) {
  for (int first = 0; first < count; first += most) {
    Status status = transfer(address + first, std::min(most, count - first), items + first);
    if (!status.ok()) return status;
  }
  return Status::Ok();
}

// Reads `count` items from `address` on, in pieces as InPieces.
template <typename T, typename Transfer>
Result<std::vector<T>> ReadInPieces(int address, int count, int most, const Transfer& transfer) {
  std::vector<T> items(count);
  if (Status status = InPieces(address, items.data(), count, most, transfer); !status.ok()) return status;
  return items;
}

}  // namespace

bool ModbusLinkOptions::IsValid(std::string* why) const {
  if (transport == Transport::kTcp && (port < 0 || port > 65535)) return Refuse(why, "port must be within [0, 65535]");
  if (transport == Transport::kRtu) {
    if (serial_device.empty()) return Refuse(why, "an RTU link needs a serial device");
    if (parity != 'N' && parity != 'E' && parity != 'O') return Refuse(why, "parity must be N, E or O");
    if (data_bits < 5 || data_bits > 8) return Refuse(why, "data bits must be within [5, 8]");
    if (stop_bits != 1 && stop_bits != 2) return Refuse(why, "stop bits must be 1 or 2");
    if (baud <= 0) return Refuse(why, "baud must be > 0");
  }
  if (unit_id < 0 || unit_id > 247) return Refuse(why, "unit id must be within [0, 247]");
  if (response_timeout_ms <= 0 || byte_timeout_ms <= 0) return Refuse(why, "timeouts must be > 0 ms");
  if (retries < 0 || retry_backoff_ms < 0) return Refuse(why, "retries and backoff must be >= 0");
  return true;
}

std::string ModbusLinkOptions::Describe() const {
  const std::string where = transport == Transport::kTcp ? "tcp " + host + ":" + std::to_string(port)
                                                         : "rtu " + serial_device + "@" + std::to_string(baud);
  return where + " unit " + std::to_string(unit_id);
}

ModbusLink::ModbusLink(std::string device, ModbusLinkOptions options)
    : device_(std::move(device)), options_(std::move(options)) {}

ModbusLink::~ModbusLink() {
  Disconnect();
  if (ctx_) modbus_free(ctx_);
}

Status ModbusLink::Fail(StatusCode code, const std::string& what) const {
  return {code, device_ + " (" + options_.Describe() + "): " + what};
}

Status ModbusLink::Connect() {
  std::string why;
  if (!options_.IsValid(&why)) return Fail(StatusCode::kInvalidArgument, why);
  if (!ctx_) {
    ctx_ = options_.transport == ModbusLinkOptions::Transport::kTcp
               ? modbus_new_tcp(options_.host.c_str(), options_.port)
               : modbus_new_rtu(options_.serial_device.c_str(), options_.baud, options_.parity, options_.data_bits,
                                options_.stop_bits);
    if (!ctx_) return Fail(StatusCode::kInvalidArgument, std::string("cannot create context: ") + modbus_strerror(errno));
    modbus_set_slave(ctx_, options_.unit_id);
    SetTimeout(ctx_, options_.response_timeout_ms, modbus_set_response_timeout);
    SetTimeout(ctx_, options_.byte_timeout_ms, modbus_set_byte_timeout);
  }
  if (connected_) return Status::Ok();
  if (modbus_connect(ctx_) != 0)
    return Fail(StatusCode::kUnavailable, std::string("cannot connect: ") + modbus_strerror(errno));
  connected_ = true;
  return Status::Ok();
}

void ModbusLink::Disconnect() {
  if (ctx_ && connected_) modbus_close(ctx_);
  connected_ = false;
}

Status ModbusLink::Transfer(Op op, int address, int count, void* data) {
  const std::string what = std::string(OpName(static_cast<int>(op))) + " " + std::to_string(address) + ".." +
                           std::to_string(address + count - 1);
  int backoff_ms = options_.retry_backoff_ms;
  std::string last_error = "not connected";
  for (int attempt = 0; attempt <= options_.retries; ++attempt) {
    if (attempt > 0) {
      std::this_thread::sleep_for(std::chrono::milliseconds(backoff_ms));
      backoff_ms *= 2;
    }
    if (!connected_) {
      const Status status = Connect();
      if (status.code() == StatusCode::kInvalidArgument) return status;
      if (!status.ok()) {
        last_error = status.message();
        continue;
      }
    }
    ++requests_;
    int done = -1;
    switch (op) {
      case Op::kWriteCoils: done = modbus_write_bits(ctx_, address, count, static_cast<const uint8_t*>(data)); break;
      case Op::kWriteRegisters:
        done = modbus_write_registers(ctx_, address, count, static_cast<const uint16_t*>(data));
        break;
      case Op::kReadCoils: done = modbus_read_bits(ctx_, address, count, static_cast<uint8_t*>(data)); break;
      case Op::kReadRegisters: done = modbus_read_registers(ctx_, address, count, static_cast<uint16_t*>(data)); break;
    }
    if (done == count) return Status::Ok();
    const int error = errno;
    if (done >= 0) return Fail(StatusCode::kDataLoss, what + ": device answered " + std::to_string(done) + " items");
    if (IsException(error))
      return Fail(StatusCode::kInvalidArgument, what + ": Modbus exception: " + modbus_strerror(error));
    // Transport failure: the reply may be half-read, so start from a fresh link.
    last_error = modbus_strerror(error);
    Disconnect();
  }
  return Fail(StatusCode::kUnavailable, what + ": " + last_error + " (after " + std::to_string(options_.retries + 1) +
                                            " attempts)");
}

Status ModbusLink::WriteCoils(int address, const std::vector<std::uint8_t>& bits) {
  std::vector<std::uint8_t> copy = bits;  // libmodbus writes from a non-const buffer
  return InPieces(address, copy.data(), static_cast<int>(copy.size()), MODBUS_MAX_WRITE_BITS,
                  [this](int at, int n, void* data) { return Transfer(Op::kWriteCoils, at, n, data); });
}

Status ModbusLink::WriteRegisters(int address, const std::vector<std::uint16_t>& values) {
  std::vector<std::uint16_t> copy = values;
  return InPieces(address, copy.data(), static_cast<int>(copy.size()), MODBUS_MAX_WRITE_REGISTERS,
                  [this](int at, int n, void* data) { return Transfer(Op::kWriteRegisters, at, n, data); });
}

Result<std::vector<std::uint8_t>> ModbusLink::ReadCoils(int address, int count) {
  return ReadInPieces<std::uint8_t>(address, count, MODBUS_MAX_READ_BITS,
                                    [this](int at, int n, void* data) { return Transfer(Op::kReadCoils, at, n, data); });
}

Result<std::vector<std::uint16_t>> ModbusLink::ReadRegisters(int address, int count) {
  return ReadInPieces<std::uint16_t>(address, count, MODBUS_MAX_READ_REGISTERS, [this](int at, int n, void* data) {
    return Transfer(Op::kReadRegisters, at, n, data);
  });
}

}  // namespace photorig::drivers
