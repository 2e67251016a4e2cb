#pragma once
// HTTP/JSON API of photorigd over a RunService. All routes under /api/v1:
//   GET  /health                      liveness and queue summary
//   GET  /devices                     the rig's devices and their state
//   POST /dry-run                     {"name", "recipe"}: step list, estimates, checks
//   POST /runs                        {"name", "recipe"}: queue a run -> 201 {"id"}
//   GET  /runs, /runs/{id}            run state, counters and stop record
//   POST /runs/{id}/pause|resume|abort
//   GET  /runs/{id}/events            progress as Server-Sent Events
//   GET  /runs/{id}/files[?under=DIR] the run's files with sizes and CRC-32
//   GET  /runs/{id}/files/{path}      a file of the run (frames/..., results/..., manifest.json)
// Errors are JSON {"error": "..."} with a 4xx/5xx status. A bearer token is
// required whenever one is configured, and must be configured to bind to
// anything but loopback.

#include "photorig/daemon/service.h"

#include <memory>
#include <string>

namespace httplib {
class Server;
}

namespace photorig::daemon {

struct ApiOptions {
  std::string bind_address = "127.0.0.1";
  int port = 8750;                        // 0: any free port (see ApiServer::port())
  std::string token;                      // bearer token; required off loopback
  std::size_t max_body_bytes = 1 << 20;
  int sse_keepalive_ms = 15000;

  bool IsValid(std::string* why) const;
};

bool IsLoopbackAddress(const std::string& address);

class ApiServer {
 public:
  ApiServer(RunService& service, ApiOptions options);
  ~ApiServer();
  // Binds the socket; throws std::runtime_error naming address and port.
  void Bind();
  int port() const { return port_; }
  // Serves until Stop(); call from its own thread.
  void Serve();
  void Stop();

 private:
  void Routes();

  RunService& service_;
  ApiOptions options_;
  std::unique_ptr<httplib::Server> server_;
  int port_ = 0;
};

}  // namespace photorig::daemon
