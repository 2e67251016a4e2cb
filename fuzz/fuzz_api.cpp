// The HTTP API: each input is the raw bytes a client sends, written to a
// socket of an ApiServer on a loopback port (one per process, over a RunService
// on the simulated dome and a temporary data root; its worker is not started,
// so submitted runs stay queued and nothing is captured). The server must
// answer every request (an error as a 4xx) and stay up; a crash, a sanitizer
// report or a 500 (an exception that escaped a route's own error handling)
// is a finding.
#include "fuzz_support.h"
#include "photorig/daemon/api_server.h"

#include <spdlog/spdlog.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <thread>

namespace {

using namespace photorig::daemon;

// Never destroyed: the server serves until the process ends.
ApiServer* server = nullptr;
std::thread* serving = nullptr;

int StartServer() {
  // The server logs each request after answering it, so the logger registry
  // could be created after StopServingAtExit is registered and then be
  // destroyed before it runs: create it first.
  spdlog::default_logger();
  ServiceOptions options;
  options.data_root = (photorig::fuzz::WorkDir() / "data").string();
  options.rig_path = photorig::fuzz::SourcePath("config/rigs/sim-dome.yaml");
  options.solve = false;
  // Never destroyed: the serving thread runs until the process ends.
  auto* service = new RunService(options);
  ApiOptions api;
  api.port = 0;
  api.max_body_bytes = 64 * 1024;
  api.sse_keepalive_ms = 500;  // an abandoned event stream notices within half a second
  server = new ApiServer(*service, api);
  server->Bind();
  serving = new std::thread([] { server->Serve(); });
  return server->port();
}

// libFuzzer ends the process with exit(), which destroys static objects
// (the logger among them) while a serving thread may still be answering the
// last request: a use-after-free that is the harness's, not the server's.
// Runs at exit before the destruction of every static object that existed
// when it was registered (after the first request, so the ones requests
// create are among them): stop accepting and wait for the serving threads.
void StopServingAtExit() {
  server->Stop();
  serving->join();
}

int Connect(int port) {
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<std::uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  // libFuzzer's own timers interrupt system calls, and on a loaded machine the
  // backlog can be full for a moment: only ten failed attempts in a row are a finding.
  constexpr int kAttempts = 10;
  for (int attempt = 1;; ++attempt) {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    if (fd < 0) std::abort();
    const timeval timeout{3, 0};  // an event stream stays open; its first bytes are enough
    ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof(timeout));
    ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof(timeout));
    if (::connect(fd, reinterpret_cast<const sockaddr*>(&address), sizeof(address)) == 0) return fd;
    const int error = errno;
    ::close(fd);
    const bool transient = error == EINTR || error == EINPROGRESS || error == EAGAIN || error == ETIMEDOUT;
    if (!transient || attempt == kAttempts) {
      errno = error;
      std::perror("fuzz_api: the server stopped accepting connections");
      std::abort();
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100 * attempt));
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const int port = StartServer();
  const int fd = Connect(port);
  for (std::size_t sent = 0; sent < size;) {
    const ssize_t n = ::send(fd, data + sent, size - sent, MSG_NOSIGNAL);
    if (n <= 0) break;  // the server may answer and close before reading everything
    sent += static_cast<std::size_t>(n);
  }
  ::shutdown(fd, SHUT_WR);
  std::string response;
  char buffer[4096];
  for (ssize_t n; (n = ::recv(fd, buffer, sizeof(buffer), 0)) > 0;) response.append(buffer, static_cast<std::size_t>(n));
  ::close(fd);
  static const bool stop_registered = std::atexit(StopServingAtExit) == 0;
  (void)stop_registered;
  if (response.rfind("HTTP/1.1 500", 0) == 0) {
    std::fprintf(stderr, "fuzz_api: 500 answer:\n%s\n", response.c_str());
    std::abort();
  }
  return 0;
}
