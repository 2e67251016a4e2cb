#include "photorig/daemon/service/internal/api_client.h"

#include "photorig/daemon/capture/run_control.h"

#include <httplib.h>

#include <chrono>
#include <cstdlib>
#include <thread>

namespace photorig::daemon {
using nlohmann::json;

namespace {

ServiceReply FromResult(const httplib::Result& result, const std::string& url) {
  if (!result) return {0, {{"error", "cannot reach photorigd at " + url + ": " + httplib::to_string(result.error())}}};
  json body;
  try {
    body = json::parse(result->body);
  } catch (const std::exception&) {
    body = {{"error", result->body}};
  }
  return {result->status, body};
}

}  // namespace

ApiClient::ApiClient(ApiClientOptions options)
    : options_(std::move(options)), client_(std::make_unique<httplib::Client>(options_.url)) {
  if (!options_.token.empty()) client_->set_bearer_token_auth(options_.token.c_str());
  client_->set_connection_timeout(options_.timeout_s, 0);
  client_->set_read_timeout(options_.timeout_s, 0);
}

ApiClient::~ApiClient() = default;

ServiceReply ApiClient::Get(const std::string& path) { return FromResult(client_->Get(path.c_str()), options_.url); }

ServiceReply ApiClient::Post(const std::string& path, const json& body) {
  return FromResult(client_->Post(path.c_str(), body.dump(), "application/json"), options_.url);
}

ApiClient::StreamEnd ApiClient::FollowOnce(const std::string& run_id,
                                           const std::function<bool(const std::string&, const json&)>& on_event,
                                           std::uint64_t* last_seq) {
  StreamEnd end;
  std::string buffer;
  httplib::Headers headers;
  if (*last_seq > 0) headers.emplace("Last-Event-ID", std::to_string(*last_seq));
  auto result = client_->Get(
      ("/api/v1/runs/" + run_id + "/events").c_str(), headers,
      [&](const httplib::Response& response) {
        end.http_status = response.status;
        return true;
      },
      [&](const char* data, std::size_t length) {
        buffer.append(data, length);
        if (end.http_status != 200) return buffer.size() < 64 * 1024;  // a refusal's body: its reason
        std::size_t block_end;
        while ((block_end = buffer.find("\n\n")) != std::string::npos) {
          const std::string block = buffer.substr(0, block_end);
          buffer.erase(0, block_end + 2);
          std::string type = "message", payload;
          std::uint64_t seq = 0;
          std::size_t start = 0;
          while (start < block.size()) {
            std::size_t eol = block.find('\n', start);
            if (eol == std::string::npos) eol = block.size();
            const std::string line = block.substr(start, eol - start);
            if (line.rfind("event: ", 0) == 0) type = line.substr(7);
            if (line.rfind("data: ", 0) == 0) payload += line.substr(6);
            if (line.rfind("id: ", 0) == 0) seq = std::strtoull(line.c_str() + 4, nullptr, 10);
            start = eol + 1;
          }
          if (payload.empty()) continue;  // keepalive comment
          json data;
          try {
            data = json::parse(payload);
          } catch (const std::exception& e) {
            end.error = std::string("malformed event: ") + e.what();
            end.stopped = true;
            return false;
          }
          if (seq > *last_seq) *last_seq = seq;
          if (!on_event(type, data) || type == "stop") {
            end.stopped = true;
            return false;
          }
        }
        return true;
      });
  if (end.http_status != 0 && end.http_status != 200) {
    end.error = "HTTP " + std::to_string(end.http_status) + " for run '" + run_id + "'";
    const json body = json::parse(buffer, nullptr, false);
    if (body.is_object() && body.contains("error") && body["error"].is_string())
      end.error += ": " + body["error"].get<std::string>();
    return end;
  }
  if (end.http_status == 200 && !end.stopped) end.http_status = 0;  // broke off before the run's end
  if (end.error.empty() && !result && !end.stopped)
    end.error = "cannot reach photorigd at " + options_.url + ": " + httplib::to_string(result.error());
  if (end.error.empty() && !end.stopped) end.error = "the event stream ended before the run did";
  return end;
}

std::string ApiClient::FollowEvents(const std::string& run_id,
                                    const std::function<bool(const std::string&, const json&)>& on_event,
                                    const Reconnect* reconnect) {
  std::uint64_t last_seq = 0;
  auto last_answer = std::chrono::steady_clock::now();
  for (;;) {
    const StreamEnd end = FollowOnce(run_id, on_event, &last_seq);
    if (end.stopped || !reconnect) return end.error;
    // Only a refusal for want of slots or a broken connection are waited out.
    if (end.http_status != 0 && end.http_status != 503) return end.error;
    const ServiceReply run = Get("/api/v1/runs/" + run_id);
    if (run.http_status == 200) {
      last_answer = std::chrono::steady_clock::now();
      if (const auto state = RunStateFromName(run.body.value("state", "")); state && IsFinal(*state)) {
        on_event("stop", StopEventData(run.body));
        return "";
      }
    } else if (run.http_status != 0) {
      return run.body.value("error", end.error);
    } else if (std::chrono::steady_clock::now() - last_answer > std::chrono::seconds(reconnect->give_up_s)) {
      return end.error + " (no answer for " + std::to_string(reconnect->give_up_s) + " s)";
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(reconnect->retry_ms));
  }
}

int ApiClient::Download(const std::string& run_id, const std::string& relative_path, std::string* bytes) {
  bytes->clear();
  std::string error;
  const int status = Download(
      run_id, relative_path,
      [bytes](const char* data, std::size_t size) {
        bytes->append(data, size);
        return true;
      },
      &error);
  if (status != 200) *bytes = error;
  return status;
}

int ApiClient::Download(const std::string& run_id, const std::string& relative_path,
                        const std::function<bool(const char*, std::size_t)>& on_data, std::string* error) {
  error->clear();
  int status = 0;
  std::string error_body;
  auto result = client_->Get(
      ("/api/v1/runs/" + run_id + "/files/" + relative_path).c_str(),
      [&status](const httplib::Response& response) {
        status = response.status;
        return true;
      },
      [&](const char* data, std::size_t size) {
        if (status != 200) {
          error_body.append(data, size);
          return true;
        }
        return on_data(data, size);
      });
  if (status == 0) {
    *error = "cannot reach photorigd at " + options_.url + ": " + httplib::to_string(result.error());
    return 0;
  }
  if (status != 200) {
    *error = "HTTP " + std::to_string(status);
    try {
      *error = json::parse(error_body).value("error", *error);
    } catch (const std::exception&) {
      if (!error_body.empty()) *error = error_body;
    }
  } else if (!result) {
    *error = "download of " + relative_path + " broke off: " + httplib::to_string(result.error());
    return 0;
  }
  return status;
}

}  // namespace photorig::daemon
