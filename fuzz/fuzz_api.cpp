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
#include <string>

namespace {

using namespace photorig::daemon;

// Never destroyed: libFuzzer ends the process with exit(), and a server
// destroyed then would outlive the logger its routes use.
ApiServer& Server() {
  static ApiServer* server = [] {
    spdlog::set_level(spdlog::level::off);  // a log line per input would cost more than the answer
    ServiceOptions options;
    options.data_root = (photorig::fuzz::WorkDir() / "data").string();
    options.rig_path = photorig::fuzz::SourcePath("config/rigs/sim-dome.yaml");
    options.solve = false;
    ApiOptions api;
    api.port = 0;
    api.max_body_bytes = 64 * 1024;
    return new ApiServer(*new RunService(options), api);
  }();
  return *server;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string response = Server().AnswerInMemory(std::string(reinterpret_cast<const char*>(data), size));
  if (response.rfind("HTTP/1.1 500", 0) == 0) {
    std::fprintf(stderr, "fuzz_api: 500 answer:\n%s\n", response.c_str());
    std::abort();
  }
  return 0;
}
