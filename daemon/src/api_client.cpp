#include "photorig/daemon/api_client.h"

#include <httplib.h>

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

std::string ApiClient::FollowEvents(const std::string& run_id,
                                    const std::function<bool(const std::string&, const json&)>& on_event) {
  std::string buffer, error;
  bool stopped = false;
  auto result = client_->Get(
      ("/api/v1/runs/" + run_id + "/events").c_str(),
      [&](const httplib::Response& response) {
        if (response.status != 200) error = "HTTP " + std::to_string(response.status) + " for run '" + run_id + "'";
        return response.status == 200;
      },
      [&](const char* data, std::size_t length) {
        buffer.append(data, length);
        std::size_t end;
        while ((end = buffer.find("\n\n")) != std::string::npos) {
          const std::string block = buffer.substr(0, end);
          buffer.erase(0, end + 2);
          std::string type = "message", payload;
          std::size_t start = 0;
          while (start < block.size()) {
            std::size_t eol = block.find('\n', start);
            if (eol == std::string::npos) eol = block.size();
            const std::string line = block.substr(start, eol - start);
            if (line.rfind("event: ", 0) == 0) type = line.substr(7);
            if (line.rfind("data: ", 0) == 0) payload += line.substr(6);
            start = eol + 1;
          }
          if (payload.empty()) continue;  // keepalive comment
          json data;
          try {
            data = json::parse(payload);
          } catch (const std::exception& e) {
            error = std::string("malformed event: ") + e.what();
            return false;
          }
          if (!on_event(type, data) || type == "stop") {
            stopped = true;
            return false;
          }
        }
        return true;
      });
  if (!error.empty()) return error;
  if (!result && !stopped) return "cannot reach photorigd at " + options_.url + ": " + httplib::to_string(result.error());
  return "";
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
