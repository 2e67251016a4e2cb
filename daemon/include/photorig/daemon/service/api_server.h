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
//   GET  /runs/{id}/preview/{path}    an image of the run tone-mapped to an 8-bit PNG
//   GET  /runs/{id}/stats/{path}      an image's size, range, histogram and clipped pixels
//   GET  /runs/{id}/values/{path}     an image's values as float32, for read-outs
//   GET  /recipes                     recipes to choose from, with their text
// Outside /api/v1, GET serves the browser interface (web_root, docs/ui.md)
// and the JavaScript libraries it uses under /vendor/.
// Errors are JSON {"error": "..."} with a 4xx/5xx status. A bearer token is
// required whenever one is configured, and must be configured to bind to
// anything but loopback. Before any route, every request is checked (see
// docs/api.md, "Request rules"): its path is UTF-8, its body has a length (no
// chunked uploads, so the body limit holds), a POST carries no form or
// text/plain body (what a foreign web page can send without asking), and a
// request without a valid token names a loopback or allowed Host and comes
// from no foreign Origin (exact names: 127.0.0.0/8 and ::1 as addresses,
// localhost, the bound address, --allow-host names).

#include "photorig/daemon/service/service.h"

#include <opencv2/core.hpp>

#include <atomic>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace httplib {
struct Request;
struct Response;
}  // namespace httplib

namespace photorig::daemon {

class HttpFront;

struct ApiOptions {
  std::string bind_address = "127.0.0.1";
  int port = 8750;                        // 0: any free port (see ApiServer::port())
  std::string token;                      // bearer token; required off loopback
  std::size_t max_body_bytes = 1 << 20;
  // Largest image GET .../values answers, in values (width x height x
  // channels); beyond it 413. Default 2^24 (64 MiB of float32): a 2048 x 2048
  // colour map, four times the largest result the rigs here write.
  std::size_t max_image_values = std::size_t{1} << 24;
  int sse_keepalive_ms = 15000;
  // Host names accepted besides loopback and bind_address (a request with a
  // valid token is accepted under any Host).
  std::vector<std::string> allowed_hosts;
  // A connection holds a worker only while a request it sent whole is
  // answered (idle and slow clients wait in the front's event loop, see
  // http_front.h), an event stream for as long as it is open: streams are
  // capped (503 beyond) below the pool size, so short requests such as
  // /health always find a free worker.
  int worker_threads = 64;
  int max_event_streams = 32;
  // A request's headers must arrive whole within this time of its first
  // byte; a keep-alive connection idle this long is closed; a body or an
  // answer stalled this long is cut off.
  int read_timeout_ms = 5000;
  int max_connections = 512;  // open at once; beyond, 503 and closed
  int listen_backlog = 128;   // connections the kernel holds before they are accepted
  // The browser interface's pages (daemon/web, installed to share/photorig/web);
  // empty: none served. Its libraries come from Debian's libjs-three and
  // libjs-chart.js under javascript_root, served as /vendor/three/ and /vendor/chart.js/.
  std::string web_root;
  std::string javascript_root = "/usr/share/javascript";

  bool IsValid(std::string* why) const;
};

// 127.0.0.0/8 or ::1 written as an address, or "localhost".
bool IsLoopbackAddress(const std::string& address);

// The port could not be bound: in use, or an address this host lacks.
class BindError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Who listens on TCP `port` on this host, from /proc: "process 1234
// (photorigd)", "another user's process", or empty when nothing listens.
std::string PortHolder(int port);

class ApiServer {
 public:
  ApiServer(RunService& service, ApiOptions options);
  ~ApiServer();
  // Binds the socket for this process alone; throws BindError naming address,
  // port and, when the port is taken, the process that holds it.
  void Bind();
  int port() const { return port_; }
  // Serves until Stop(); call from its own thread.
  void Serve();
  void Stop();
  // One request's answer without a socket or Bind(): the routes, limits and
  // checks of a served request, from raw request bytes (the API's fuzz target).
  std::string AnswerInMemory(const std::string& request);

 private:
  void Routes();
  void InstallGuards();  // the checks before routing, and the error and exception answers
  void MountWebInterface();
  // The routes' handlers (docs/api.md).
  void Health(const httplib::Request& req, httplib::Response& res);
  void Devices(const httplib::Request& req, httplib::Response& res);
  void DryRun(const httplib::Request& req, httplib::Response& res);
  void Submit(const httplib::Request& req, httplib::Response& res);
  void ListRuns(const httplib::Request& req, httplib::Response& res);
  void GetRun(const httplib::Request& req, httplib::Response& res);
  void ControlRun(const httplib::Request& req, httplib::Response& res);
  void StreamEvents(const httplib::Request& req, httplib::Response& res);
  void ListFiles(const httplib::Request& req, httplib::Response& res);
  void SendFile(const httplib::Request& req, httplib::Response& res);
  void SendPreview(const httplib::Request& req, httplib::Response& res);
  void SendImageStats(const httplib::Request& req, httplib::Response& res);
  void SendImageValues(const httplib::Request& req, httplib::Response& res);
  void ListRecipes(const httplib::Request& req, httplib::Response& res);
  // The image a preview, stats or values route names, as floats; nullopt
  // with the error answered when there is none or it cannot be read.
  std::optional<cv::Mat> ReadRunImage(const httplib::Request& req, httplib::Response& res);

  RunService& service_;
  ApiOptions options_;
  std::atomic<int> open_event_streams_{0};
  std::unique_ptr<HttpFront> server_;
  int port_ = 0;
};

}  // namespace photorig::daemon
