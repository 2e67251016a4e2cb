#include "photorig/daemon/api_server.h"

#include <httplib.h>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <fstream>

namespace photorig::daemon {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

void Reply(httplib::Response& res, const ServiceReply& reply) {
  res.status = reply.http_status;
  // Messages can quote request bytes (a recipe key, a parse error's context)
  // that are not UTF-8; they are replaced (U+FFFD) rather than failing the answer.
  res.set_content(reply.body.dump(-1, ' ', false, json::error_handler_t::replace), "application/json");
}

void ErrorReply(httplib::Response& res, int status, const std::string& message) {
  Reply(res, {status, {{"error", message}}});
}

bool ConstantTimeEquals(const std::string& a, const std::string& b) {
  if (a.size() != b.size()) return false;
  unsigned char diff = 0;
  for (std::size_t i = 0; i < a.size(); ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
  return diff == 0;
}

// {"name": "...", "recipe": "yaml"} from a JSON body, or the YAML itself.
bool ParseRecipeBody(const httplib::Request& req, httplib::Response& res, std::string* name, std::string* yaml) {
  if (req.get_header_value("Content-Type").rfind("application/json", 0) == 0) {
    try {
      const json body = json::parse(req.body);
      *yaml = body.at("recipe").get<std::string>();
      *name = body.value("name", "recipe.yaml");
    } catch (const std::exception& e) {
      ErrorReply(res, 400, std::string("expected {\"name\": ..., \"recipe\": \"<yaml>\"}: ") + e.what());
      return false;
    }
  } else {
    *yaml = req.body;
    *name = req.has_param("name") ? req.get_param_value("name") : "recipe.yaml";
  }
  if (name->size() > 200 || name->find('\n') != std::string::npos) {
    ErrorReply(res, 400, "recipe name too long or multi-line");
    return false;
  }
  return true;
}

const char* ContentType(const fs::path& path) {
  const std::string ext = path.extension().string();
  if (ext == ".json") return "application/json";
  if (ext == ".jsonl") return "application/x-ndjson";
  if (ext == ".png") return "image/png";
  if (ext == ".tiff" || ext == ".tif") return "image/tiff";
  if (ext == ".yaml") return "application/yaml";
  return "application/octet-stream";
}

std::string SseEvent(const RunEvent& event) {
  return "id: " + std::to_string(event.seq) + "\nevent: " + event.type + "\ndata: " + event.data.dump() + "\n\n";
}

}  // namespace

bool IsLoopbackAddress(const std::string& address) {
  return address == "127.0.0.1" || address == "::1" || address == "localhost" || address.rfind("127.", 0) == 0;
}

bool ApiOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& message) {
    if (why) *why = message;
    return false;
  };
  if (port < 0 || port > 65535) return fail("port must be within [0, 65535]");
  if (!IsLoopbackAddress(bind_address) && token.empty())
    return fail("binding to " + bind_address + " (not loopback) requires a bearer token");
  if (!token.empty() && token.size() < 16) return fail("the bearer token must be at least 16 characters");
  if (max_body_bytes == 0) return fail("max_body_bytes must be > 0");
  return true;
}

ApiServer::ApiServer(RunService& service, ApiOptions options)
    : service_(service), options_(std::move(options)), server_(std::make_unique<httplib::Server>()) {
  std::string why;
  if (!options_.IsValid(&why)) throw std::runtime_error("API options: " + why);
  server_->set_payload_max_length(options_.max_body_bytes);
  Routes();
}

ApiServer::~ApiServer() { Stop(); }

void ApiServer::Bind() {
  port_ = options_.port == 0 ? server_->bind_to_any_port(options_.bind_address)
                             : (server_->bind_to_port(options_.bind_address, options_.port) ? options_.port : -1);
  if (port_ <= 0)
    throw std::runtime_error("cannot listen on " + options_.bind_address + ":" + std::to_string(options_.port));
}

void ApiServer::Serve() { server_->listen_after_bind(); }
void ApiServer::Stop() { server_->stop(); }

void ApiServer::Routes() {
  httplib::Server& s = *server_;
  const std::string token = options_.token;
  s.set_pre_routing_handler([token](const httplib::Request& req, httplib::Response& res) {
    if (token.empty()) return httplib::Server::HandlerResponse::Unhandled;
    if (ConstantTimeEquals(req.get_header_value("Authorization"), "Bearer " + token))
      return httplib::Server::HandlerResponse::Unhandled;
    res.set_header("WWW-Authenticate", "Bearer");
    ErrorReply(res, 401, "missing or wrong bearer token");
    return httplib::Server::HandlerResponse::Handled;
  });
  s.set_logger([](const httplib::Request& req, const httplib::Response& res) {
    spdlog::debug("event=http method={} path={} status={}", req.method, req.path, res.status);
  });
  s.set_error_handler([](const httplib::Request&, httplib::Response& res) {
    if (res.body.empty()) ErrorReply(res, res.status, res.status == 413 ? "request body too large" : "no such route");
  });
  s.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
    try {
      std::rethrow_exception(ep);
    } catch (const std::exception& e) {
      ErrorReply(res, 500, e.what());
    }
  });

  s.Get("/api/v1/health", [this](const httplib::Request&, httplib::Response& res) { Reply(res, service_.Health()); });
  s.Get("/api/v1/devices", [this](const httplib::Request&, httplib::Response& res) { Reply(res, service_.Devices()); });
  s.Post("/api/v1/dry-run", [this](const httplib::Request& req, httplib::Response& res) {
    std::string name, yaml;
    if (ParseRecipeBody(req, res, &name, &yaml)) Reply(res, service_.DryRun(name, yaml));
  });
  s.Post("/api/v1/runs", [this](const httplib::Request& req, httplib::Response& res) {
    std::string name, yaml;
    if (ParseRecipeBody(req, res, &name, &yaml)) Reply(res, service_.Submit(name, yaml));
  });
  s.Get("/api/v1/runs", [this](const httplib::Request&, httplib::Response& res) { Reply(res, service_.ListRuns()); });
  s.Get(R"(/api/v1/runs/([^/]+))", [this](const httplib::Request& req, httplib::Response& res) {
    Reply(res, service_.GetRun(req.matches[1]));
  });
  s.Post(R"(/api/v1/runs/([^/]+)/(pause|resume|abort))", [this](const httplib::Request& req, httplib::Response& res) {
    const std::string id = req.matches[1];
    const std::string action = req.matches[2];
    if (const ServiceReply run = service_.GetRun(id); run.http_status != 200) return Reply(res, run);
    Reply(res, action == "pause" ? service_.Pause(id) : action == "resume" ? service_.Resume(id) : service_.Abort(id));
  });
  s.Get(R"(/api/v1/runs/([^/]+)/events)", [this](const httplib::Request& req, httplib::Response& res) {
    const std::string id = req.matches[1];
    const ServiceReply run = service_.GetRun(id);
    if (run.http_status != 200) return Reply(res, run);
    std::uint64_t start = 0;
    if (req.has_header("Last-Event-ID")) start = std::strtoull(req.get_header_value("Last-Event-ID").c_str(), nullptr, 10);
    auto last = std::make_shared<std::uint64_t>(start);
    auto idle_ms = std::make_shared<int>(0);
    res.set_header("Cache-Control", "no-cache");
    res.set_chunked_content_provider("text/event-stream", [this, id, last, idle_ms](std::size_t, httplib::DataSink& sink) {
      const auto events = service_.EventsAfter(id, *last, 500);
      for (const RunEvent& event : events) {
        const std::string text = SseEvent(event);
        if (!sink.write(text.data(), text.size())) return false;
        *last = event.seq;
        if (event.type == "stop") {
          sink.done();
          return true;
        }
      }
      if (events.empty()) {
        // A run that finished before this stream began: its stop record, then the end.
        if (service_.IsRunFinal(id)) {
          const json body = service_.GetRun(id).body;
          const std::string text = SseEvent({*last + 1, id, "stop", {{"state", body.value("state", "")},
                                                                      {"reason", body.value("reason", "")},
                                                                      {"frames", body.value("frames", 0)},
                                                                      {"steps_total", body.value("steps_total", 0)},
                                                                      {"retries", body.value("retries", 0)},
                                                                      {"dropped_frames", body.value("dropped_frames", 0)}}});
          sink.write(text.data(), text.size());
          sink.done();
          return true;
        }
        *idle_ms += 500;
        if (*idle_ms >= options_.sse_keepalive_ms) {
          *idle_ms = 0;
          static const char kComment[] = ": keepalive\n\n";
          if (!sink.write(kComment, sizeof(kComment) - 1)) return false;
        }
      }
      return true;
    });
  });
  s.Get(R"(/api/v1/runs/([^/]+)/files/(.+))", [this](const httplib::Request& req, httplib::Response& res) {
    const std::string directory = service_.RunDirectory(req.matches[1]);
    if (directory.empty() || !fs::exists(directory)) return ErrorReply(res, 404, "no run '" + std::string(req.matches[1]) + "'");
    const std::string relative = req.matches[2];
    const fs::path root = fs::weakly_canonical(directory);
    const fs::path target = fs::weakly_canonical(root / relative);
    // Resolve first, then check: "..", absolute paths and symlinks all end up outside the root.
    const auto mismatch = std::mismatch(root.begin(), root.end(), target.begin(), target.end());
    if (relative.find('\0') != std::string::npos || fs::path(relative).is_absolute() || mismatch.first != root.end())
      return ErrorReply(res, 400, "path '" + relative + "' leaves the run directory");
    if (!fs::is_regular_file(target)) return ErrorReply(res, 404, "no file '" + relative + "' in the run");
    std::ifstream in(target, std::ios::binary);
    std::string content((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    res.set_content(std::move(content), ContentType(target));
  });
}

}  // namespace photorig::daemon
