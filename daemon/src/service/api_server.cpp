#include "photorig/daemon/service/api_server.h"

#include "photorig/config/yaml_node.h"
#include "photorig/daemon/io/image_io.h"
#include "photorig/daemon/io/json_fields.h"
#include "http_front.h"

#include <opencv2/imgproc.hpp>

#include <httplib.h>
#include <spdlog/spdlog.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <tuple>
#include <vector>

namespace photorig::daemon {
using solvers::core::Refuse;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

void Reply(httplib::Response& res, const ServiceReply& reply) {
  res.status = reply.http_status;
  // Messages can quote request bytes (a recipe key, a parse error's context)
  // and runs stored before names were checked can hold bytes that are not
  // UTF-8: replaced (U+FFFD) rather than failing the whole answer.
  res.set_content(reply.body.dump(-1, ' ', false, json::error_handler_t::replace), "application/json");
  if (reply.retry_after_s > 0) res.set_header("Retry-After", std::to_string(reply.retry_after_s));
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

// {"name": "...", "recipe": "yaml", "path": "..."} from a JSON body, or the
// YAML itself with ?name= and ?path=.
bool ParseRecipeBody(const httplib::Request& req, httplib::Response& res, std::string* name, std::string* yaml,
                     std::string* path) {
  std::string type = req.get_header_value("Content-Type");
  std::transform(type.begin(), type.end(), type.begin(), [](unsigned char c) { return std::tolower(c); });
  if (type.rfind("application/json", 0) == 0) {  // media types are case-insensitive (RFC 9110)
    static const std::string kShape = "expected {\"recipe\": \"<yaml>\", \"name\": \"...\", \"path\": \"/abs/...\"}";
    json body;
    try {
      body = json::parse(req.body);
    } catch (const json::parse_error& e) {
      ErrorReply(res, 400, "the body is not valid JSON (" + WithoutJsonLibraryTag(e.what()) + "): " + kShape);
      return false;
    }
    if (!body.is_object()) {
      ErrorReply(res, 400, "the body is not a JSON object: " + kShape);
      return false;
    }
    // Each field named when it is missing or not a string.
    for (const auto& [field, out, fallback] : {std::tuple<const char*, std::string*, const char*>{"recipe", yaml, nullptr},
                                               {"name", name, "recipe.yaml"},
                                               {"path", path, ""}}) {
      const auto found = body.find(field);
      if (found == body.end() && fallback) {
        *out = fallback;
      } else if (found == body.end() || !found->is_string()) {
        ErrorReply(res, 400, std::string("'") + field + "' " + (found == body.end() ? "is missing" : "must be a string") +
                                 ": " + kShape);
        return false;
      } else {
        *out = found->get<std::string>();
      }
    }
  } else {
    *yaml = req.body;
    *name = req.has_param("name") ? req.get_param_value("name") : "recipe.yaml";
    *path = req.has_param("path") ? req.get_param_value("path") : "";
  }
  if (!path->empty() && path->front() != '/') {
    ErrorReply(res, 400, "path '" + *path + "' must be absolute: the recipe's own path, so that its recipe.rig "
                                            "resolves as `photorig run` would resolve it");
    return false;
  }
  if (name->size() > 200 || name->find('\n') != std::string::npos || !config::IsValidUtf8(*name) ||
      path->size() > 4096 || path->find('\n') != std::string::npos || !config::IsValidUtf8(*path)) {
    ErrorReply(res, 400, "recipe name or path too long, multi-line or not UTF-8");
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
  return "id: " + std::to_string(event.seq) + "\nevent: " + event.type +
         "\ndata: " + event.data.dump(-1, ' ', false, json::error_handler_t::replace) + "\n\n";
}

std::string Lower(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

// The host of a Host header or an origin's authority ("127.0.0.1:8750",
// "[::1]:8750"), without the port.
std::string HostName(const std::string& authority) {
  if (!authority.empty() && authority.front() == '[') return Lower(authority.substr(1, authority.find(']') - 1));
  return Lower(authority.substr(0, authority.rfind(':')));
}

// Whether `host` (from a Host header or an Origin) names this daemon to a
// browser: a loopback address, the address it listens on, or a name the
// operator allowed. Exact comparisons: a prefix test lets a rebinding name
// such as 127.0.0.1.attacker.example through.
bool IsOwnHost(const std::string& host, const ApiOptions& options) {
  return IsLoopbackAddress(host) || host == Lower(options.bind_address) ||
         std::any_of(options.allowed_hosts.begin(), options.allowed_hosts.end(),
                     [&](const std::string& name) { return Lower(name) == host; });
}

// What a web page may POST to another origin without the browser asking it
// first (a CORS "simple request"): never accepted, so a page cannot queue a run.
bool IsFormOrPlainText(const std::string& content_type) {
  std::string media = Lower(content_type.substr(0, content_type.find(';')));
  media.erase(media.find_last_not_of(" \t") + 1);
  return media == "text/plain" || media == "application/x-www-form-urlencoded" || media == "multipart/form-data";
}

struct Refusal {
  int status = 0;  // 0: the request may proceed
  std::string message;
};

// The checks every request passes before any route: see docs/api.md, "Request rules".
Refusal CheckRequest(const httplib::Request& req, const ApiOptions& options) {
  if (!config::IsValidUtf8(req.path)) return {400, "the request path is not UTF-8"};
  // cpp-httplib reads a chunked body whole before its handler can refuse it,
  // whatever the payload limit: only bodies with a length are read.
  if (req.has_header("Transfer-Encoding"))
    return {411, "send the body with a Content-Length (chunked uploads are not accepted)"};
  const bool state_changing = req.method != "GET" && req.method != "HEAD" && req.method != "OPTIONS";
  if (state_changing && IsFormOrPlainText(req.get_header_value("Content-Type")))
    return {415, "send JSON (application/json) or YAML (application/yaml), not a form or text/plain"};
  bool authenticated = false;
  // The interface's pages and libraries hold no data and a browser cannot
  // attach a token to the request that loads a page: they are served without
  // one (the Host check below still applies); their scripts send it to /api/.
  const bool static_file = (req.method == "GET" || req.method == "HEAD") && req.path.rfind("/api/", 0) != 0;
  if (!options.token.empty() && !static_file) {
    if (!ConstantTimeEquals(req.get_header_value("Authorization"), "Bearer " + options.token))
      return {401, "missing or wrong bearer token"};
    authenticated = true;  // a page in a browser cannot know the token
  }
  if (authenticated) return {};
  // A page served from elsewhere reaches a loopback daemon only through the
  // browser: under its own host name (DNS rebinding) or with its own Origin.
  if (req.has_header("Host") && !IsOwnHost(HostName(req.get_header_value("Host")), options))
    return {403, "Host '" + HostName(req.get_header_value("Host")) + "' is not this daemon's (see --allow-host)"};
  if (req.has_header("Origin")) {
    const std::string origin = Lower(req.get_header_value("Origin"));
    const bool own = origin.rfind("http://", 0) == 0 && IsOwnHost(HostName(origin.substr(7)), options);
    if (!own) return {403, "requests from the page at '" + origin + "' are not accepted (see --allow-host)"};
    if (state_changing && origin != "http://" + Lower(req.get_header_value("Host")))
      return {403, "cross-origin requests may not change anything"};
  }
  return {};
}

// Frees an event-stream slot when the stream's response is destroyed, however it ended.
class StreamSlot {
 public:
  explicit StreamSlot(std::atomic<int>& open) : open_(open) {}
  ~StreamSlot() { --open_; }
  StreamSlot(const StreamSlot&) = delete;
  StreamSlot& operator=(const StreamSlot&) = delete;

 private:
  std::atomic<int>& open_;
};


// An image of a run as float channels in (R, G, B) = (x, y, z) order: float
// TIFFs as written (image_io.h), PNG frames and previews converted.
cv::Mat ReadImageAsFloat(const std::string& file) {
  const std::string ext = Lower(fs::path(file).extension().string());
  if (ext == ".tiff" || ext == ".tif") return ReadFloatTiff(file);
  if (ext != ".png") throw std::invalid_argument("not an image: only .png, .tif and .tiff files have values");
  cv::Mat image = ReadImage(file);
  if (image.channels() == 4) cv::cvtColor(image, image, cv::COLOR_BGRA2RGB);
  else if (image.channels() == 3) cv::cvtColor(image, image, cv::COLOR_BGR2RGB);
  cv::Mat values;
  image.convertTo(values, CV_32F);
  return values;
}

// The value at `fraction` of the sorted finite values of every channel.
double Percentile(const cv::Mat& image, double fraction) {
  std::vector<float> values;
  values.reserve(image.total() * image.channels());
  const cv::Mat flat = image.reshape(1, 1);
  for (int i = 0; i < flat.cols; ++i)
    if (std::isfinite(flat.at<float>(0, i))) values.push_back(flat.at<float>(0, i));
  if (values.empty()) return 0.0;
  const std::size_t k = std::min(values.size() - 1, static_cast<std::size_t>(fraction * (values.size() - 1) + 0.5));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

double NumberParam(const httplib::Request& req, const char* name, double fallback) {
  if (!req.has_param(name)) return fallback;
  const std::string text = req.get_param_value(name);
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  if (end == text.c_str() || *end != '\0' || !std::isfinite(value))
    throw std::invalid_argument(std::string("?") + name + "= must be a number, got '" + text + "'");
  return value;
}

// The tone mapping of GET .../preview: `low` .. `high` (default: the finite
// values' minimum .. 99.5th percentile) to 0 .. 1, then the power 1 / `gamma`
// (default 2.2, a display's), NaN black, and pixels at or above `saturation`
// (when given) red. Shrunk to at most `max_side` pixels on its longer side.
struct Preview {
  cv::Mat bgr8;
  double low = 0, high = 0;
  int clipped = 0;
};

Preview TonemapPreview(const cv::Mat& values, const httplib::Request& req) {
  Preview preview;
  double min_value = 0;
  cv::Mat finite_mask = values.reshape(1) == values.reshape(1);
  cv::minMaxLoc(values.reshape(1), &min_value, nullptr, nullptr, nullptr, finite_mask);
  preview.low = NumberParam(req, "low", min_value);
  preview.high = NumberParam(req, "high", Percentile(values, 0.995));
  // Both given and out of order is a mistake; a default that falls at or
  // below the other bound (a flat image, a `low` above most values) widens.
  if (req.has_param("low") && req.has_param("high") && !(preview.high > preview.low))
    throw std::invalid_argument("?low= must be below ?high=, got " + req.get_param_value("low") + " and " +
                                req.get_param_value("high"));
  if (!(preview.high > preview.low)) preview.high = preview.low + 1.0;
  const double gamma = NumberParam(req, "gamma", 2.2);
  const double max_side = NumberParam(req, "max_side", 1024);
  if (!(gamma > 0)) throw std::invalid_argument("?gamma= must be > 0, got '" + req.get_param_value("gamma") + "'");
  if (max_side < 16 || max_side > 8192)
    throw std::invalid_argument("?max_side= must be within [16, 8192], got '" + req.get_param_value("max_side") + "'");
  cv::Mat scaled = (values - preview.low) / (preview.high - preview.low);
  cv::patchNaNs(scaled, 0.0);
  cv::max(scaled, 0.0, scaled);
  cv::min(scaled, 1.0, scaled);
  cv::pow(scaled, 1.0 / gamma, scaled);
  cv::Mat bytes;
  scaled.convertTo(bytes, CV_8U, 255.0);
  if (bytes.channels() == 1) cv::cvtColor(bytes, preview.bgr8, cv::COLOR_GRAY2BGR);
  else if (bytes.channels() == 3) cv::cvtColor(bytes, preview.bgr8, cv::COLOR_RGB2BGR);
  else throw std::invalid_argument("previews show 1- or 3-channel images");
  if (req.has_param("saturation")) {
    cv::Mat clipped;
    cv::compare(values.reshape(1, values.rows * values.cols), NumberParam(req, "saturation", 0), clipped, cv::CMP_GE);
    cv::reduce(clipped, clipped, 1, cv::REDUCE_MAX);
    clipped = clipped.reshape(1, values.rows);
    preview.clipped = cv::countNonZero(clipped);
    preview.bgr8.setTo(cv::Scalar(0, 0, 255), clipped);
  }
  const double longer = std::max(values.cols, values.rows);
  if (longer > max_side)
    cv::resize(preview.bgr8, preview.bgr8, cv::Size(), max_side / longer, max_side / longer, cv::INTER_AREA);
  return preview;
}

// GET .../stats: size, finite range, a 64-bin histogram over it (all
// channels together) and, with ?saturation=, the pixels at or above it.
json ImageStats(const cv::Mat& values, const httplib::Request& req) {
  constexpr int kBins = 64;
  double low = 0, high = 0;
  cv::Mat finite_mask = values.reshape(1) == values.reshape(1);
  cv::minMaxLoc(values.reshape(1), &low, &high, nullptr, nullptr, finite_mask);
  std::vector<std::uint64_t> histogram(kBins, 0);
  const cv::Mat flat = values.reshape(1, 1);
  const double width = std::max(high - low, 1e-30);
  std::uint64_t clipped = 0;
  const bool has_saturation = req.has_param("saturation");
  const double saturation = NumberParam(req, "saturation", 0);
  for (int i = 0; i < flat.cols; ++i) {
    const float v = flat.at<float>(0, i);
    if (!std::isfinite(v)) continue;
    ++histogram[std::min(kBins - 1, static_cast<int>((v - low) / width * kBins))];
    if (has_saturation && v >= saturation) ++clipped;
  }
  json stats = {{"width", values.cols}, {"height", values.rows}, {"channels", values.channels()},
                {"min", low},           {"max", high},           {"histogram", histogram}};
  if (has_saturation) stats["clipped"] = clipped;
  return stats;
}

}  // namespace

bool IsLoopbackAddress(const std::string& address) {
  in_addr v4{};
  in6_addr v6{};
  if (::inet_pton(AF_INET, address.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
  if (::inet_pton(AF_INET6, address.c_str(), &v6) == 1) return IN6_IS_ADDR_LOOPBACK(&v6);
  return Lower(address) == "localhost";
}

bool ApiOptions::IsValid(std::string* why) const {
  if (port < 0 || port > 65535) return Refuse(why, "port must be within [0, 65535]");
  if (!IsLoopbackAddress(bind_address) && token.empty())
    return Refuse(why, "binding to " + bind_address + " (not loopback) requires a bearer token");
  if (!token.empty() && token.size() < 16) return Refuse(why, "the bearer token must be at least 16 characters");
  if (max_body_bytes == 0) return Refuse(why, "max_body_bytes must be > 0");
  if (max_image_values == 0) return Refuse(why, "max_image_values must be > 0");
  if (max_event_streams < 1) return Refuse(why, "max_event_streams must be >= 1");
  if (worker_threads < max_event_streams + 8)
    return Refuse(why, "worker_threads must exceed max_event_streams by at least 8, so short requests are served");
  if (read_timeout_ms < 100) return Refuse(why, "read_timeout_ms must be >= 100");
  if (listen_backlog < 1) return Refuse(why, "listen_backlog must be >= 1");
  if (max_connections < worker_threads) return Refuse(why, "max_connections must be >= worker_threads");
  return true;
}

namespace {

FrontOptions FrontOf(const ApiOptions& options) {
  FrontOptions front;
  front.worker_threads = options.worker_threads;
  front.header_timeout_ms = options.read_timeout_ms;
  front.idle_timeout_ms = options.read_timeout_ms;
  front.io_timeout_ms = options.read_timeout_ms;
  front.max_connections = options.max_connections;
  front.listen_backlog = options.listen_backlog;
  return front;
}

// The inode of the socket listening on TCP `port` from /proc/net/tcp or
// tcp6 (lines "sl local_address rem_address st ... inode"), 0 if none.
std::string ListeningInode(int port) {
  char wanted[8];
  std::snprintf(wanted, sizeof(wanted), ":%04X", port);
  for (const char* table : {"/proc/net/tcp", "/proc/net/tcp6"}) {
    std::ifstream in(table);
    std::string line;
    std::getline(in, line);  // the column names
    while (std::getline(in, line)) {
      std::istringstream fields(line);
      std::string slot, local, remote, state, queues, timer, retransmits, uid, timeout, inode;
      fields >> slot >> local >> remote >> state >> queues >> timer >> retransmits >> uid >> timeout >> inode;
      if (state == "0A" && local.size() > 5 && local.compare(local.size() - 5, 5, wanted) == 0) return inode;
    }
  }
  return "";
}

}  // namespace

std::string PortHolder(int port) {
  const std::string inode = ListeningInode(port);
  if (inode.empty()) return "";
  const std::string target = "socket:[" + inode + "]";
  std::error_code error;
  for (const auto& process : fs::directory_iterator("/proc", error)) {
    const std::string pid = process.path().filename().string();
    if (pid.find_first_not_of("0123456789") != std::string::npos) continue;
    for (const auto& fd : fs::directory_iterator(process.path() / "fd", error)) {
      if (fs::read_symlink(fd.path(), error).string() != target) continue;
      std::string name;
      std::getline(std::ifstream(process.path() / "comm"), name);
      return "process " + pid + " (" + name + ")";
    }
    error.clear();  // processes of other users cannot be looked into
  }
  return "another user's process";
}

ApiServer::ApiServer(RunService& service, ApiOptions options)
    : service_(service), options_(std::move(options)) {
  std::string why;
  if (!options_.IsValid(&why)) throw std::runtime_error("API options: " + why);
  server_ = std::make_unique<HttpFront>(FrontOf(options_));
  server_->set_payload_max_length(options_.max_body_bytes);
  Routes();
}

ApiServer::~ApiServer() { Stop(); }

void ApiServer::Bind() {
  int error_number = 0;
  port_ = server_->Listen(options_.bind_address, options_.port, &error_number);
  if (port_ > 0) return;
  std::string message = "cannot listen on " + options_.bind_address + ":" + std::to_string(options_.port) + ": " +
                        std::strerror(error_number);
  if (error_number == EADDRINUSE) {
    const std::string holder = PortHolder(options_.port);
    message += holder.empty() ? "" : " (held by " + holder + ")";
    message += "; stop that daemon first, or choose another --port";
  }
  throw BindError(message);
}

void ApiServer::Serve() { server_->Serve(); }
void ApiServer::Stop() { server_->Stop(); }
std::string ApiServer::AnswerInMemory(const std::string& request) { return server_->AnswerInMemory(request); }

void ApiServer::InstallGuards() {
  httplib::Server& s = *server_;
  // Runs once the headers are in, before the body is read.
  s.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    const Refusal refusal = CheckRequest(req, options_);
    if (refusal.status == 0) return httplib::Server::HandlerResponse::Unhandled;
    if (refusal.status == 401) res.set_header("WWW-Authenticate", "Bearer");
    if (refusal.status == 411 || refusal.status == 413) res.set_header("Connection", "close");  // the body stays unread
    ErrorReply(res, refusal.status, refusal.message);
    return httplib::Server::HandlerResponse::Handled;
  });
  s.set_logger([](const httplib::Request& req, const httplib::Response& res) {
    spdlog::debug("event=http method={} path={} status={}", req.method, req.path, res.status);
  });
  s.set_error_handler([](const httplib::Request&, httplib::Response& res) {
    if (!res.body.empty()) return;
    ErrorReply(res, res.status,
               res.status == 413   ? "request body too large"
               : res.status == 404 ? "no such route"
                                   : "malformed request (a POST needs a Content-Length, even with no body: send "
                                     "Content-Type: application/json and the body {})");
  });
  // Every error a handler lets through ends here as a 500; the daemon keeps serving.
  s.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
    try {
      std::rethrow_exception(ep);
    } catch (const std::exception& e) {
      ErrorReply(res, 500, e.what());
    } catch (...) {
      ErrorReply(res, 500, "unknown error");
    }
  });
}

void ApiServer::Routes() {
  InstallGuards();
  // The API (docs/api.md): one named handler per route.
  using Handler = void (ApiServer::*)(const httplib::Request&, httplib::Response&);
  struct Route {
    bool post;
    const char* pattern;
    Handler handle;
  };
  static const Route kRoutes[] = {
      {false, "/api/v1/health", &ApiServer::Health},
      {false, "/api/v1/devices", &ApiServer::Devices},
      {true, "/api/v1/dry-run", &ApiServer::DryRun},
      {true, "/api/v1/runs", &ApiServer::Submit},
      {false, "/api/v1/runs", &ApiServer::ListRuns},
      {false, R"(/api/v1/runs/([^/]+))", &ApiServer::GetRun},
      {true, R"(/api/v1/runs/([^/]+)/(pause|resume|abort))", &ApiServer::ControlRun},
      {false, R"(/api/v1/runs/([^/]+)/events)", &ApiServer::StreamEvents},
      {false, R"(/api/v1/runs/([^/]+)/files)", &ApiServer::ListFiles},
      {false, R"(/api/v1/runs/([^/]+)/files/(.+))", &ApiServer::SendFile},
      // Images of a run for the browser interface (docs/api.md, "Images").
      {false, R"(/api/v1/runs/([^/]+)/preview/(.+))", &ApiServer::SendPreview},
      {false, R"(/api/v1/runs/([^/]+)/stats/(.+))", &ApiServer::SendImageStats},
      {false, R"(/api/v1/runs/([^/]+)/values/(.+))", &ApiServer::SendImageValues},
      {false, "/api/v1/recipes", &ApiServer::ListRecipes},
  };
  for (const Route& route : kRoutes) {
    auto handler = [this, handle = route.handle](const httplib::Request& req, httplib::Response& res) {
      (this->*handle)(req, res);
    };
    if (route.post) server_->Post(route.pattern, handler);
    else server_->Get(route.pattern, handler);
  }
  // A route asked with a method it does not take: 405 with the methods it
  // does (Allow, RFC 9110), not "no such route".
  std::map<std::string, std::pair<bool, bool>> takes;  // pattern: GET, POST
  for (const Route& route : kRoutes) (route.post ? takes[route.pattern].second : takes[route.pattern].first) = true;
  for (const auto& [pattern, get_post] : takes) {
    const std::string methods = get_post.first && get_post.second ? "GET, POST" : get_post.first ? "GET" : "POST";
    const auto refuse = [methods](const httplib::Request& req, httplib::Response& res) {
      res.set_header("Allow", methods);
      ErrorReply(res, 405, req.method + " is not a method of this route: it takes " + methods);
    };
    if (methods.find("GET") == std::string::npos) server_->Get(pattern, refuse);
    if (methods.find("POST") == std::string::npos) server_->Post(pattern, refuse);
    server_->Put(pattern, refuse);
    server_->Delete(pattern, refuse);
    server_->Patch(pattern, refuse);
  }
  MountWebInterface();
}

void ApiServer::Health(const httplib::Request&, httplib::Response& res) { Reply(res, service_.Health()); }
void ApiServer::Devices(const httplib::Request&, httplib::Response& res) { Reply(res, service_.Devices()); }
void ApiServer::ListRuns(const httplib::Request& req, httplib::Response& res) {
  try {
    const double limit = NumberParam(req, "limit", RunService::kRunsPerPage);
    if (limit != std::floor(limit) || limit < 1 || limit > RunService::kMaxRunsPerPage)
      throw std::invalid_argument("?limit= must be a whole number within [1, " +
                                  std::to_string(RunService::kMaxRunsPerPage) + "], got '" +
                                  req.get_param_value("limit") + "'");
    Reply(res, service_.ListRuns(static_cast<int>(limit), req.has_param("before") ? req.get_param_value("before") : ""));
  } catch (const std::invalid_argument& e) {
    ErrorReply(res, 400, e.what());
  }
}
void ApiServer::ListRecipes(const httplib::Request&, httplib::Response& res) { Reply(res, service_.ListRecipes()); }
void ApiServer::GetRun(const httplib::Request& req, httplib::Response& res) { Reply(res, service_.GetRun(req.matches[1])); }

void ApiServer::DryRun(const httplib::Request& req, httplib::Response& res) {
  std::string name, yaml, path;
  if (ParseRecipeBody(req, res, &name, &yaml, &path)) Reply(res, service_.DryRun(name, yaml, path));
}

void ApiServer::Submit(const httplib::Request& req, httplib::Response& res) {
  std::string name, yaml, path;
  if (ParseRecipeBody(req, res, &name, &yaml, &path)) Reply(res, service_.Submit(name, yaml, path));
}

void ApiServer::ControlRun(const httplib::Request& req, httplib::Response& res) {
  const std::string id = req.matches[1];
  const std::string action = req.matches[2];
  if (const ServiceReply run = service_.GetRun(id); run.http_status != 200) return Reply(res, run);
  Reply(res, action == "pause" ? service_.Pause(id) : action == "resume" ? service_.Resume(id) : service_.Abort(id));
}

void ApiServer::StreamEvents(const httplib::Request& req, httplib::Response& res) {
  const std::string id = req.matches[1];
  const ServiceReply run = service_.GetRun(id);
  if (run.http_status != 200) return Reply(res, run);
  std::uint64_t start = 0;
  if (req.has_header("Last-Event-ID")) {
    // Strictly a whole number: strtoull would wrap "-1" to the last id there is.
    const std::string given = req.get_header_value("Last-Event-ID");
    const auto [end, error] = std::from_chars(given.data(), given.data() + given.size(), start);
    if (error != std::errc() || end != given.data() + given.size())
      return ErrorReply(res, 400, "Last-Event-ID '" + given + "' is not an event id (a whole number)");
  }
  auto last = std::make_shared<std::uint64_t>(start);
  auto idle_ms = std::make_shared<int>(0);
  if (++open_event_streams_ > options_.max_event_streams) {
    --open_event_streams_;
    return ErrorReply(res, 503, "too many open event streams (" + std::to_string(options_.max_event_streams) + ")");
  }
  auto slot = std::make_shared<StreamSlot>(open_event_streams_);
  res.set_header("Cache-Control", "no-cache");
  res.set_chunked_content_provider("text/event-stream", [this, id, last, idle_ms, slot](std::size_t, httplib::DataSink& sink) {
    // A client that hung up frees its slot now, not at the next keepalive write.
    if (!sink.is_writable()) return false;
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
        const std::string text = SseEvent({*last + 1, id, "stop", StopEventData(service_.GetRun(id).body)});
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
}

void ApiServer::ListFiles(const httplib::Request& req, httplib::Response& res) {
  Reply(res, service_.ListFiles(req.matches[1], req.has_param("under") ? req.get_param_value("under") : ""));
}

void ApiServer::SendFile(const httplib::Request& req, httplib::Response& res) {
  const std::string relative = req.matches[2];
  std::string file;
  if (const ServiceReply resolved = service_.ResolveRunPath(req.matches[1], relative, &file); resolved.http_status != 200)
    return Reply(res, resolved);
  std::error_code error;
  const std::uintmax_t size = fs::file_size(file, error);
  if (error || !fs::is_regular_file(file, error)) return ErrorReply(res, 404, "no file '" + relative + "' in the run");
  if (size == 0) return res.set_content("", ContentType(file));
  // Streamed from the file, so a large result never sits in memory whole.
  auto in = std::make_shared<std::ifstream>(file, std::ios::binary);
  res.set_content_provider(size, ContentType(file), [in](std::size_t offset, std::size_t length, httplib::DataSink& sink) {
    std::vector<char> buffer(std::min<std::size_t>(length, 1 << 20));
    in->seekg(static_cast<std::streamoff>(offset));
    in->read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    return in->gcount() > 0 && sink.write(buffer.data(), static_cast<std::size_t>(in->gcount()));
  });
}

std::optional<cv::Mat> ApiServer::ReadRunImage(const httplib::Request& req, httplib::Response& res) {
  const std::string relative = req.matches[2];
  std::string file;
  if (const ServiceReply resolved = service_.ResolveRunPath(req.matches[1], relative, &file); resolved.http_status != 200) {
    Reply(res, resolved);
    return std::nullopt;
  }
  // The error_code form: a name the file system refuses (too long) is a 404 like any other.
  std::error_code error;
  if (!fs::is_regular_file(file, error)) {
    ErrorReply(res, 404, "no file '" + relative + "' in the run");
    return std::nullopt;
  }
  try {
    return ReadImageAsFloat(file);
  } catch (const std::exception& e) {
    // A file that is no image, or a damaged one: the client's request for
    // this file cannot be met (400), said without the daemon's own paths.
    std::string why = e.what();
    for (std::size_t at; (at = why.find(file)) != std::string::npos;) why.replace(at, file.size(), relative);
    ErrorReply(res, 400, "'" + relative + "' in the run cannot be shown: " + why);
    return std::nullopt;
  }
}

void ApiServer::SendPreview(const httplib::Request& req, httplib::Response& res) {
  const std::optional<cv::Mat> values = ReadRunImage(req, res);
  if (!values) return;
  try {
    const Preview preview = TonemapPreview(*values, req);
    std::vector<std::uint8_t> png;
    std::string why;
    if (!solvers::codecs::EncodeImage(solvers::codecs::ImageEncoding::kPng, preview.bgr8, &png, &why))
      throw std::runtime_error("cannot encode the preview: " + why);
    res.set_header("X-Preview-Low", std::to_string(preview.low));
    res.set_header("X-Preview-High", std::to_string(preview.high));
    if (req.has_param("saturation")) res.set_header("X-Preview-Clipped", std::to_string(preview.clipped));
    res.set_content(reinterpret_cast<const char*>(png.data()), png.size(), "image/png");
  } catch (const std::invalid_argument& e) {
    ErrorReply(res, 400, e.what());
  }
}

void ApiServer::SendImageStats(const httplib::Request& req, httplib::Response& res) {
  const std::optional<cv::Mat> values = ReadRunImage(req, res);
  if (!values) return;
  try {
    Reply(res, {200, ImageStats(*values, req)});
  } catch (const std::invalid_argument& e) {
    ErrorReply(res, 400, e.what());
  }
}

void ApiServer::SendImageValues(const httplib::Request& req, httplib::Response& res) {
  const std::optional<cv::Mat> values = ReadRunImage(req, res);
  if (!values) return;
  const std::size_t count = values->total() * static_cast<std::size_t>(values->channels());
  const std::size_t limit = options_.max_image_values;
  if (count > limit)
    return ErrorReply(res, 413, "the image has " + std::to_string(count) + " values (" + std::to_string(values->cols) +
                                    " x " + std::to_string(values->rows) + " x " + std::to_string(values->channels()) +
                                    "), more than the " + std::to_string(limit) +
                                    " one request answers; read it shrunk with preview, or its stats");
  const cv::Mat contiguous = values->isContinuous() ? *values : values->clone();
  res.set_header("X-Image-Width", std::to_string(values->cols));
  res.set_header("X-Image-Height", std::to_string(values->rows));
  res.set_header("X-Image-Channels", std::to_string(values->channels()));
  res.set_content(reinterpret_cast<const char*>(contiguous.data), contiguous.total() * contiguous.elemSize(),
                  "application/octet-stream");
}

// The browser interface, and its libraries from Debian's packages.
void ApiServer::MountWebInterface() {
  if (options_.web_root.empty()) return;
  httplib::Server& s = *server_;
  for (const char* ext : {"js", "mjs"}) s.set_file_extension_and_mimetype_mapping(ext, "text/javascript");
  s.set_file_extension_and_mimetype_mapping("css", "text/css");
  s.set_file_extension_and_mimetype_mapping("html", "text/html");
  s.set_file_extension_and_mimetype_mapping("svg", "image/svg+xml");
  if (!s.set_mount_point("/", options_.web_root)) throw std::runtime_error("web_root " + options_.web_root + " is not a folder");
  for (const char* library : {"three", "chart.js"}) {
    const fs::path folder = fs::path(options_.javascript_root) / library;
    if (fs::is_directory(folder)) s.set_mount_point(std::string("/vendor/") + library, folder.string());
    else spdlog::warn("event=ui_library_missing folder={} (install Debian's libjs-{})", folder.string(), library);
  }
}

}  // namespace photorig::daemon
