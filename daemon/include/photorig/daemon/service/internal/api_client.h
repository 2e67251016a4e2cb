#pragma once
// Client side of the photorigd API (api_server.h), used by the photorig CLI
// and the API tests.

#include "photorig/daemon/service/service.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

namespace httplib {
class Client;
}

namespace photorig::daemon {

// How FollowEvents carries on when a stream breaks off or is refused (503:
// every stream slot taken) while the run goes on: it opens the stream again
// after `retry_ms`, resuming after the last event seen (Last-Event-ID), and
// gives up once the daemon has not answered for `give_up_s`.
struct Reconnect {
  int retry_ms = 1000;
  int give_up_s = 60;
};

struct ApiClientOptions {
  std::string url = "http://127.0.0.1:8750";  // scheme://host:port
  std::string token;                           // sent as a bearer token when set
  int timeout_s = 30;
};

class ApiClient {
 public:
  explicit ApiClient(ApiClientOptions options);
  ~ApiClient();

  // http_status 0 and an "error" body when the daemon cannot be reached.
  ServiceReply Get(const std::string& path);
  ServiceReply Post(const std::string& path, const nlohmann::json& body);
  // Follows a run's Server-Sent Events until `on_event` returns false or the
  // stream ends (after the "stop" event). Returns an error message, or empty.
  // With `reconnect`, a lost or refused stream is opened again while the run
  // goes on; a run found ended meanwhile gets its "stop" event from the run's record.
  std::string FollowEvents(const std::string& run_id,
                           const std::function<bool(const std::string& type, const nlohmann::json& data)>& on_event,
                           const Reconnect* reconnect = nullptr);
  // The raw bytes of a run's file; http_status as in Get.
  int Download(const std::string& run_id, const std::string& relative_path, std::string* bytes);
  // Streams a run's file to `on_data` as it arrives (return false to stop).
  // Returns the HTTP status: 200 when the whole file arrived; 0 when the
  // daemon could not be reached or the transfer broke off (or `on_data`
  // stopped it). For any status but 200 nothing reaches `on_data` and
  // `*error` says why (the daemon's message, or the transport's).
  int Download(const std::string& run_id, const std::string& relative_path,
               const std::function<bool(const char* data, std::size_t size)>& on_data, std::string* error);

 private:
  struct StreamEnd {
    int http_status = 0;  // 0: no answer, or the stream broke off
    bool stopped = false;  // the "stop" event came, or `on_event` ended it
    std::string error;
  };
  // One connection's worth of FollowEvents from after *last_seq, which it advances.
  StreamEnd FollowOnce(const std::string& run_id,
                       const std::function<bool(const std::string&, const nlohmann::json&)>& on_event,
                       std::uint64_t* last_seq);

  ApiClientOptions options_;
  std::unique_ptr<httplib::Client> client_;
};

}  // namespace photorig::daemon
