// The HTTP API: each input is the raw bytes a client sends, answered by an
// ApiServer over a RunService on the simulated dome and a temporary data root
// (its worker is not started, so submitted runs stay queued and nothing is
// captured). The bytes go through the server's own request parsing, limits
// and routes in memory (ApiServer::AnswerInMemory), without a socket: a
// connection per input would cost more than the request itself. The server
// must answer every request (an error as a 4xx); a crash, a sanitizer report
// or a 500 (an exception that escaped a route's own error handling) is a
// finding. The socket side (slow clients, hang-ups, limits on connections)
// is tested in tests/daemon.
#include "fuzz_support.h"
#include "photorig/daemon/service/api_server.h"

#include <spdlog/spdlog.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <system_error>

namespace {

using namespace photorig::daemon;

// Runs an input may add before the service starts again on an empty data
// root. Each input's answer should depend on the input, not on every run the
// fuzzer ever submitted: an unbounded queue made each run list cost more
// (200 runs serialised per page, 42 % of the time after 860,000 inputs)
// and a finding depend on history no single input replays. A few runs keep
// the listing, paging and per-run routes covered.
constexpr int kRunsBeforeRestart = 8;

struct Service {
  // A new data root for each service; the one before is removed.
  Service() {
    static int generation = 0;
    data_root = photorig::fuzz::WorkDir() / ("data-" + std::to_string(generation++));
    ServiceOptions options;
    options.data_root = data_root.string();
    options.rig_path = photorig::fuzz::SourcePath("config/rigs/sim-dome.yaml");
    options.solve = false;
    ApiOptions api;
    api.port = 0;
    api.max_body_bytes = 64 * 1024;
    runs = std::make_unique<RunService>(options);
    server = std::make_unique<ApiServer>(*runs, api);
  }
  ~Service() {
    server.reset();
    runs.reset();
    std::error_code ignored;
    std::filesystem::remove_all(data_root, ignored);
  }
  std::filesystem::path data_root;
  std::unique_ptr<RunService> runs;
  std::unique_ptr<ApiServer> server;
  int runs_added = 0;
};

// Never destroyed at exit: libFuzzer ends the process with exit(), and a
// server destroyed then would outlive the logger its routes use.
Service*& Current() {
  static Service* service = [] {
    spdlog::set_level(spdlog::level::off);  // a log line per input would cost more than the answer
    return new Service;
  }();
  return service;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Service*& service = Current();
  const std::string response = service->server->AnswerInMemory(std::string(reinterpret_cast<const char*>(data), size));
  if (response.rfind("HTTP/1.1 500", 0) == 0) {
    std::fprintf(stderr, "fuzz_api: 500 answer:\n%s\n", response.c_str());
    std::abort();
  }
  // 201 Created: a run (or a batch of them) was queued.
  if (response.rfind("HTTP/1.1 201", 0) == 0 && ++service->runs_added >= kRunsBeforeRestart) {
    delete service;
    service = new Service;
  }
  return 0;
}
