#include "photorig/sim/modbus/server.h"

#include <modbus/modbus.h>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <pty.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>

namespace photorig::sim {
namespace {

double NowSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

bool IsWrite(int function) {
  return function == MODBUS_FC_WRITE_SINGLE_COIL || function == MODBUS_FC_WRITE_SINGLE_REGISTER ||
         function == MODBUS_FC_WRITE_MULTIPLE_COILS || function == MODBUS_FC_WRITE_MULTIPLE_REGISTERS ||
         function == MODBUS_FC_WRITE_AND_READ_REGISTERS || function == MODBUS_FC_MASK_WRITE_REGISTER;
}

}  // namespace

SimModbusServer::SimModbusServer(ModbusServerOptions options) : options_(std::move(options)) {}

SimModbusServer::~SimModbusServer() { Stop(); }

void SimModbusServer::AddPeer(std::shared_ptr<ModbusPeer> peer) { peers_.push_back(std::move(peer)); }

Status SimModbusServer::StartTcp(const std::string& host, int port) {
  if (thread_.joinable()) return {StatusCode::kFailedPrecondition, "sim modbus server: already running"};
  listen_fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  const int yes = 1;
  ::setsockopt(listen_fd_, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<std::uint16_t>(port));
  if (::inet_pton(AF_INET, host.c_str(), &address.sin_addr) != 1)
    return {StatusCode::kInvalidArgument, "sim modbus server: bad IPv4 address '" + host + "'"};
  if (::bind(listen_fd_, reinterpret_cast<sockaddr*>(&address), sizeof(address)) != 0 ||
      ::listen(listen_fd_, 8) != 0) {
    const std::string why = std::strerror(errno);
    ::close(listen_fd_);
    listen_fd_ = -1;
    return {StatusCode::kUnavailable, "sim modbus server: cannot listen on " + host + ":" + std::to_string(port) +
                                          ": " + why};
  }
  socklen_t length = sizeof(address);
  ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&address), &length);
  port_ = ntohs(address.sin_port);
  ctx_ = modbus_new_tcp(host.c_str(), port_);
  return Launch(false);
}

Status SimModbusServer::StartRtu() {
  if (thread_.joinable()) return {StatusCode::kFailedPrecondition, "sim modbus server: already running"};
  char name[256] = {};
  if (::openpty(&pty_master_, &pty_slave_, name, nullptr, nullptr) != 0)
    return {StatusCode::kUnavailable, std::string("sim modbus server: openpty: ") + std::strerror(errno)};
  // Raw bytes both ways; the server keeps the slave open so a client
  // reconnecting never sees a hang-up.
  termios tio{};
  ::tcgetattr(pty_slave_, &tio);
  ::cfmakeraw(&tio);
  ::tcsetattr(pty_slave_, TCSANOW, &tio);
  ::fcntl(pty_master_, F_SETFD, FD_CLOEXEC);
  ::fcntl(pty_slave_, F_SETFD, FD_CLOEXEC);
  rtu_path_ = name;
  ctx_ = modbus_new_rtu(rtu_path_.c_str(), options_.rtu_baud, 'N', 8, 1);
  modbus_set_slave(ctx_, options_.unit_id);
  modbus_set_socket(ctx_, pty_master_);
  return Launch(true);
}

Status SimModbusServer::Launch(bool rtu) {
  rtu_ = rtu;
  map_ = modbus_mapping_new(options_.coils, 0, options_.holding_registers, 0);
  stop_ = false;
  thread_ = std::thread([this] { Serve(); });
  return Status::Ok();
}

void SimModbusServer::Stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  if (ctx_) {
    modbus_set_socket(ctx_, -1);
    modbus_free(ctx_);
    ctx_ = nullptr;
  }
  for (int* fd : {&listen_fd_, &pty_master_, &pty_slave_})
    if (*fd >= 0) {
      ::close(*fd);
      *fd = -1;
    }
  if (map_) {
    modbus_mapping_free(map_);
    map_ = nullptr;
  }
}

bool SimModbusServer::Handle(const std::uint8_t* request, int length) {
  const std::uint64_t index = requests_++;
  const int header = modbus_get_header_length(ctx_);
  if (length < header + 1) return true;
  const int function = request[header];
  int address = -1, count = 0;
  if (length >= header + 5) {
    address = (request[header + 1] << 8) | request[header + 2];
    const bool single = function == MODBUS_FC_WRITE_SINGLE_COIL || function == MODBUS_FC_WRITE_SINGLE_REGISTER;
    count = single ? 1 : (request[header + 3] << 8) | request[header + 4];
  }
  const ModbusServerFaults& faults = options_.faults;
  if (faults.disconnect_at.count(index)) return false;
  if (faults.exception_at.count(index)) {
    modbus_reply_exception(ctx_, request, MODBUS_EXCEPTION_SLAVE_OR_SERVER_FAILURE);
    return true;
  }
  for (int bad : faults.exception_addresses)
    if (address >= 0 && bad >= address && bad < address + count) {
      modbus_reply_exception(ctx_, request, MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS);
      return true;
    }
  std::lock_guard lock(map_mutex_);
  const double now = NowSeconds();
  for (auto& peer : peers_) peer->Advance(map_, now);
  if (IsWrite(function)) {
    // Apply the write (the reply echoes it), then let the devices react, so a
    // read that follows sees the device's state, as on real hardware.
    modbus_reply(ctx_, request, length, map_);
    for (auto& peer : peers_) peer->AfterWrite(map_, now);
  } else {
    modbus_reply(ctx_, request, length, map_);
  }
  return true;
}

void SimModbusServer::Serve() {
  std::vector<int> clients;
  std::uint8_t request[MODBUS_TCP_MAX_ADU_LENGTH > MODBUS_RTU_MAX_ADU_LENGTH ? MODBUS_TCP_MAX_ADU_LENGTH
                                                                            : MODBUS_RTU_MAX_ADU_LENGTH];
  auto close_clients = [&] {
    for (int fd : clients) ::close(fd);
    clients.clear();
  };
  while (!stop_) {
    if (drop_clients_.exchange(false)) close_clients();
    fd_set readable;
    FD_ZERO(&readable);
    int highest = -1;
    auto watch = [&](int fd) {
      FD_SET(fd, &readable);
      highest = std::max(highest, fd);
    };
    if (rtu_) watch(pty_master_);
    else {
      watch(listen_fd_);
      for (int fd : clients) watch(fd);
    }
    timeval timeout{0, 10000};  // wake to notice Stop and to run the devices' clocks
    const int ready = ::select(highest + 1, &readable, nullptr, nullptr, &timeout);
    {
      std::lock_guard lock(map_mutex_);
      const double now = NowSeconds();
      for (auto& peer : peers_) peer->Tick(map_, now);
    }
    if (ready <= 0) continue;
    if (rtu_) {
      const int length = modbus_receive(ctx_, request);
      if (length > 0) Handle(request, length);  // a dropped RTU reply is simply silence
      else if (length < 0) modbus_flush(ctx_);
      continue;
    }
    if (FD_ISSET(listen_fd_, &readable)) {
      const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC);
      if (fd >= 0) clients.push_back(fd);
    }
    for (auto it = clients.begin(); it != clients.end();) {
      bool keep = true;
      if (FD_ISSET(*it, &readable)) {
        modbus_set_socket(ctx_, *it);
        const int length = modbus_receive(ctx_, request);
        keep = length > 0 ? Handle(request, length) : length == 0;
      }
      if (keep) {
        ++it;
      } else {
        ::close(*it);
        it = clients.erase(it);
      }
    }
  }
  close_clients();
}

}  // namespace photorig::sim
