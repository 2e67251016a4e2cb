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

}  // namespace

bool ModbusLinkOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& text) {
    if (why) *why = text;
    return false;
  };
  if (transport == Transport::kTcp && (port < 0 || port > 65535)) return fail("port must be within [0, 65535]");
  if (transport == Transport::kRtu) {
    if (serial_device.empty()) return fail("an RTU link needs a serial device");
    if (parity != 'N' && parity != 'E' && parity != 'O') return fail("parity must be N, E or O");
    if (data_bits < 5 || data_bits > 8) return fail("data bits must be within [5, 8]");
    if (stop_bits != 1 && stop_bits != 2) return fail("stop bits must be 1 or 2");
    if (baud <= 0) return fail("baud must be > 0");
  }
  if (unit_id < 0 || unit_id > 247) return fail("unit id must be within [0, 247]");
  if (response_timeout_ms <= 0 || byte_timeout_ms <= 0) return fail("timeouts must be > 0 ms");
  if (retries < 0 || retry_backoff_ms < 0) return fail("retries and backoff must be >= 0");
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
  std::vector<std::uint8_t> chunk;
  for (std::size_t first = 0; first < bits.size(); first += MODBUS_MAX_WRITE_BITS) {
    const std::size_t n = std::min<std::size_t>(MODBUS_MAX_WRITE_BITS, bits.size() - first);
    chunk.assign(bits.begin() + first, bits.begin() + first + n);
    Status status = Transfer(Op::kWriteCoils, address + static_cast<int>(first), static_cast<int>(n), chunk.data());
    if (!status.ok()) return status;
  }
  return Status::Ok();
}

Status ModbusLink::WriteRegisters(int address, const std::vector<std::uint16_t>& values) {
  std::vector<std::uint16_t> chunk;
  for (std::size_t first = 0; first < values.size(); first += MODBUS_MAX_WRITE_REGISTERS) {
    const std::size_t n = std::min<std::size_t>(MODBUS_MAX_WRITE_REGISTERS, values.size() - first);
    chunk.assign(values.begin() + first, values.begin() + first + n);
    Status status =
        Transfer(Op::kWriteRegisters, address + static_cast<int>(first), static_cast<int>(n), chunk.data());
    if (!status.ok()) return status;
  }
  return Status::Ok();
}

Result<std::vector<std::uint8_t>> ModbusLink::ReadCoils(int address, int count) {
  std::vector<std::uint8_t> bits(count);
  for (int first = 0; first < count; first += MODBUS_MAX_READ_BITS) {
    const int n = std::min(MODBUS_MAX_READ_BITS, count - first);
    Status status = Transfer(Op::kReadCoils, address + first, n, bits.data() + first);
    if (!status.ok()) return status;
  }
  return bits;
}

Result<std::vector<std::uint16_t>> ModbusLink::ReadRegisters(int address, int count) {
  std::vector<std::uint16_t> values(count);
  for (int first = 0; first < count; first += MODBUS_MAX_READ_REGISTERS) {
    const int n = std::min(MODBUS_MAX_READ_REGISTERS, count - first);
    Status status = Transfer(Op::kReadRegisters, address + first, n, values.data() + first);
    if (!status.ok()) return status;
  }
  return values;
}

}  // namespace photorig::drivers
