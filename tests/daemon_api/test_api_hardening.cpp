// The API under hostile or careless clients: recipes that expand without
// bound, bytes that are not UTF-8, requests from other web origins, chunked
// uploads, and many slow or long-lived connections.

#include "photorig/daemon/service/internal/api_client.h"
#include "photorig/daemon/service/api_server.h"
#include "photorig/daemon/service/run_queue.h"
#include "served_api.h"
#include "test_support.h"

#include <gtest/gtest.h>
#include <httplib.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <mutex>
#include <thread>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using photorig::testing::SmallRecipeYaml;
using photorig::testing::SmallRigYaml;
using photorig::testing::TempDir;

const char kToken[] = "a-test-token-of-sufficient-length";

// A raw connection, for what no well-behaved client sends.
class RawConnection {
 public:
  explicit RawConnection(int port) : fd_(::socket(AF_INET, SOCK_STREAM, 0)) {
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<std::uint16_t>(port));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connected_ = ::connect(fd_, reinterpret_cast<sockaddr*>(&address), sizeof(address)) == 0;
  }
  ~RawConnection() { ::close(fd_); }
  bool connected() const { return connected_; }
  bool Send(const std::string& bytes) { return ::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(bytes.size()); }
  // Reads until the end of the response headers; returns the status code (0 if the connection ended first).
  int fd() const { return fd_; }
  int ReadStatus() {
    std::string head;
    char c;
    while (head.find("\r\n\r\n") == std::string::npos && ::recv(fd_, &c, 1, 0) == 1) head += c;
    if (head.rfind("HTTP/1.1 ", 0) != 0) return 0;
    return std::atoi(head.c_str() + 9);
  }

 private:
  int fd_;
  bool connected_ = false;
};

class Hardening : public ::testing::Test {
 protected:
  void StartDaemon(const std::string& token = "", const std::function<void(const std::string&)>& before = nullptr,
                   const std::function<void(ApiOptions&)>& adjust = nullptr) {
    ServiceOptions options;
    options.data_root = (dir_.path() / "data").string();
    options.rig_path = dir_.Write("rig.yaml", SmallRigYaml());
    options.solve = false;
    if (before) before(options.data_root);
    ApiOptions api;
    api.port = 0;
    api.token = token;
    api.max_body_bytes = 64 * 1024;
    api.worker_threads = 24;
    api.max_event_streams = 12;
    if (adjust) adjust(api);
    served_ = std::make_unique<ServedApi>(options, api);
  }
  ApiClient Client() { return served_->Client(); }
  std::string Url() const { return served_->Url(); }
  httplib::Client Raw() {
    httplib::Client client(Url());
    client.set_read_timeout(20, 0);
    return client;
  }

  TempDir dir_;
  std::unique_ptr<ServedApi> served_;
};

// Finding 1: four lines that expand to four million steps.
TEST_F(Hardening, AnAliasedRecipeIsRefusedWith413AndTheDaemonStaysUp) {
  StartDaemon();
  ApiClient client = Client();
  const std::string recipe =
      "recipe: {name: amp}\ncapture:\n  steps:\n    - &g {dark: {count: 1000, repeat: 1000}}\n    - *g\n    - *g\n"
      "    - *g\n";
  for (const char* route : {"/api/v1/dry-run", "/api/v1/runs"}) {
    const auto reply = client.Post(route, {{"name", "amp.yaml"}, {"recipe", recipe}});
    EXPECT_EQ(reply.http_status, 413) << reply.body.dump();
    EXPECT_EQ(reply.body["error"].get<std::string>().rfind("amp.yaml:4:", 0), 0u) << reply.body.dump();
    EXPECT_EQ(reply.body["line"], 4);
  }
  // A pose grid whose expansion is too large: 413 too, as docs/api.md says, with its position.
  const std::string grid =
      "recipe: {name: grid}\ncapture:\n  steps:\n    - poses:\n        grid: {light_arm_deg: {start: 0, step: 0.01, "
      "count: 1000}, camera_arm_deg: {start: 0, step: 0.01, count: 1000}}\n";
  const std::string axis =
      "recipe: {name: axis}\ncapture:\n  steps:\n    - poses:\n        grid: {light_arm_deg: {start: 0, step: 0.01, "
      "count: 1000000}}\n";
  for (const std::string& bomb : {grid, axis})
    for (const char* route : {"/api/v1/dry-run", "/api/v1/runs"}) {
      const auto reply = client.Post(route, {{"name", "grid.yaml"}, {"recipe", bomb}});
      EXPECT_EQ(reply.http_status, 413) << reply.body.dump();
      EXPECT_EQ(reply.body["line"], 5) << reply.body.dump();
    }
  EXPECT_EQ(client.Get("/api/v1/health").http_status, 200);
  EXPECT_TRUE(client.Get("/api/v1/runs").body["runs"].empty());

  // A large plan within the limits lists its first steps only.
  const auto big = client.Post("/api/v1/dry-run", {{"recipe", SmallRecipeYaml("", 1000) + "    - dark: {count: 1000, repeat: 20}\n"}});
  ASSERT_EQ(big.http_status, 200) << big.body.dump();
  EXPECT_EQ(big.body["frames"], 21004);
  EXPECT_EQ(big.body["steps_listed"], 10000);
  EXPECT_EQ(big.body["steps"].size(), 10000u);
}

// A fuzzer's queue, grown by every run it submitted, took GET /runs past 10
// s: the list is a page of the newest runs, a client pages back with
// ?before=, and the health check counts queued runs without reading them.
TEST_F(Hardening, TheRunListIsAPageOfTheNewestRuns) {
  std::vector<std::string> ids;
  StartDaemon("", [&](const std::string& data_root) {
    fs::create_directories(data_root);
    RunQueue queue((fs::path(data_root) / "queue.sqlite").string());
    for (int i = 0; i < 250; ++i) {
      QueuedRun run = queue.Add("stored", 1, nullptr);
      run.state = RunState::kFailed;  // nothing for the worker to start
      queue.Update(run);
      ids.push_back(run.id);
    }
  });
  ApiClient client = Client();
  auto listed_ids = [](const ServiceReply& reply) {
    std::vector<std::string> listed;
    for (const json& run : reply.body["runs"]) listed.push_back(run["id"]);
    return listed;
  };
  const auto newest = client.Get("/api/v1/runs");
  ASSERT_EQ(newest.http_status, 200) << newest.body.dump();
  EXPECT_EQ(listed_ids(newest), std::vector<std::string>(ids.begin() + 50, ids.end()));  // 200, oldest first
  EXPECT_EQ(newest.body["older"], true);
  ASSERT_EQ(newest.body["before"], ids[50]);
  const auto back = client.Get("/api/v1/runs?before=" + ids[50]);
  EXPECT_EQ(listed_ids(back), std::vector<std::string>(ids.begin(), ids.begin() + 50));
  EXPECT_EQ(back.body["older"], false);
  EXPECT_FALSE(back.body.contains("before"));
  EXPECT_EQ(listed_ids(client.Get("/api/v1/runs?limit=3")), std::vector<std::string>(ids.end() - 3, ids.end()));
  for (const char* limit : {"0", "1001", "2.5", "abc", "-3"})
    EXPECT_EQ(client.Get(std::string("/api/v1/runs?limit=") + limit).http_status, 400) << limit;
  EXPECT_EQ(client.Get("/api/v1/runs?before=000001-nowhere").http_status, 404);
  const auto health = client.Get("/api/v1/health");
  EXPECT_EQ(health.http_status, 200) << health.body.dump();
}

// Finding 4: a name that is not UTF-8 broke every later listing.
TEST_F(Hardening, BytesThatAreNotUtf8AreRefusedAndStoredOnesStillList) {
  std::string stored_id;
  StartDaemon("", [&](const std::string& data_root) {
    // A run stored before names were checked.
    fs::create_directories(data_root);
    RunQueue queue((fs::path(data_root) / "queue.sqlite").string());
    QueuedRun run = queue.Add("old\xff-name", 1, nullptr);
    run.state = RunState::kFailed;
    run.reason = "reason with \xfe byte";
    queue.Update(run);
    stored_id = run.id;
  });
  ApiClient client = Client();
  const auto runs = client.Get("/api/v1/runs");
  ASSERT_EQ(runs.http_status, 200) << runs.body.dump();
  ASSERT_EQ(runs.body["runs"].size(), 1u);
  EXPECT_EQ(runs.body["runs"][0]["recipe"], "old\xef\xbf\xbd-name");  // U+FFFD
  EXPECT_EQ(client.Get("/api/v1/runs/" + stored_id).http_status, 200);

  httplib::Client raw = Raw();
  // A raw YAML body with 0xFF in the recipe name: refused with its position, nothing queued.
  const auto yaml = raw.Post("/api/v1/runs?name=bad.yaml", "recipe: {name: a\xff}\ncapture: {steps: [dark: {}]}\n",
                             "application/yaml");
  ASSERT_TRUE(yaml);
  EXPECT_EQ(yaml->status, 400);
  EXPECT_NE(yaml->body.find("bad.yaml:1:17"), std::string::npos) << yaml->body;
  const auto name = raw.Post("/api/v1/runs?name=bad%FF.yaml", SmallRecipeYaml(), "application/yaml");
  ASSERT_TRUE(name);
  EXPECT_EQ(name->status, 400);
  EXPECT_EQ(client.Get("/api/v1/runs").body["runs"].size(), 1u);

  // Invalid UTF-8 in the path.
  const auto path = raw.Get("/api/v1/runs/%FF%FE");
  ASSERT_TRUE(path);
  EXPECT_EQ(path->status, 400) << path->body;
  EXPECT_TRUE(json::accept(path->body));
}

// Finding 3: a page on another origin queued and aborted runs.
TEST_F(Hardening, ForeignPagesCannotChangeAnything) {
  StartDaemon();
  httplib::Client raw = Raw();
  const std::string body = json{{"recipe", SmallRecipeYaml()}}.dump();
  // The content types a page may POST cross-origin without asking first.
  for (const char* type : {"text/plain", "text/plain;charset=UTF-8", "application/x-www-form-urlencoded",
                           "multipart/form-data; boundary=x"}) {
    const auto reply = raw.Post("/api/v1/runs", body, type);
    ASSERT_TRUE(reply);
    EXPECT_EQ(reply->status, 415) << type;
  }
  const auto foreign_origin = raw.Post("/api/v1/runs", {{"Origin", "http://evil.example"}}, body, "application/json");
  ASSERT_TRUE(foreign_origin);
  EXPECT_EQ(foreign_origin->status, 403);
  EXPECT_EQ(raw.Post("/api/v1/runs", {{"Origin", "null"}}, body, "application/json")->status, 403);
  // DNS rebinding: the page's own host name resolving to 127.0.0.1.
  EXPECT_EQ(raw.Post("/api/v1/runs", {{"Host", "evil.example:8750"}}, body, "application/json")->status, 403);
  EXPECT_EQ(raw.Get("/api/v1/runs", {{"Host", "evil.example"}})->status, 403);
  EXPECT_TRUE(Client().Get("/api/v1/runs").body["runs"].empty());

  // The daemon's own origin, the CLI (no Origin) and localhost are served.
  const std::string own = "127.0.0.1:" + std::to_string(served_->port());
  const auto same = raw.Post("/api/v1/runs", {{"Origin", "http://" + own}}, body, "application/json");
  ASSERT_TRUE(same);
  EXPECT_EQ(same->status, 201) << same->body;
  const std::string id = json::parse(same->body)["id"];
  EXPECT_EQ(raw.Get("/api/v1/health", {{"Host", "localhost:8750"}})->status, 200);
  const auto abort = raw.Post("/api/v1/runs/" + id + "/abort", {{"Origin", "http://evil.example"}}, "{}", "application/json");
  EXPECT_EQ(abort->status, 403);
  EXPECT_EQ(raw.Post("/api/v1/runs/" + id + "/abort", "{}", "text/plain")->status, 415);
  // YAML bodies are still accepted as such.
  EXPECT_EQ(raw.Post("/api/v1/dry-run?name=small.yaml", SmallRecipeYaml(), "application/yaml")->status, 200);
}

// Finding 3: recipes wrote and probed files anywhere.
TEST_F(Hardening, PathsARecipeNamesStayInTheDataRoot) {
  StartDaemon();
  ApiClient client = Client();
  const std::string existing = dir_.Write("outside.ply", "ply\nformat ascii 1.0\nend_header\n");
  const std::string missing = (dir_.path() / "missing.ply").string();
  auto with_scene = [](const std::string& path) {
    return "recipe: {name: s}\nsample:\n  sim_scene: {shape: mesh, path: " + path +
           "}\ncapture:\n  steps:\n    - dark: {count: 1}\n";
  };
  const auto probe_existing = client.Post("/api/v1/dry-run", {{"name", "s.yaml"}, {"recipe", with_scene(existing)}});
  const auto probe_missing = client.Post("/api/v1/dry-run", {{"name", "s.yaml"}, {"recipe", with_scene(missing)}});
  const auto probe_relative = client.Post("/api/v1/dry-run", {{"name", "s.yaml"}, {"recipe", with_scene("../../outside.ply")}});
  EXPECT_EQ(probe_existing.http_status, 400);
  EXPECT_EQ(probe_relative.http_status, 400);
  // Whether the file exists outside is not told.
  EXPECT_EQ(probe_existing.body["error"], probe_missing.body["error"]) << probe_existing.body.dump();
  EXPECT_NE(probe_existing.body["error"].get<std::string>().find("s.yaml:3:34: sample.sim_scene.path: must lie inside"),
            std::string::npos)
      << probe_existing.body.dump();

  auto with_out_rig = [](const std::string& path) {
    return "recipe: {name: c}\ncapture:\n  steps:\n    - dark: {count: 1}\nsolve:\n  - light_calibration: {out_rig: " +
           path + "}\n";
  };
  for (const std::string& path : {(dir_.path() / "evil.yaml").string(), std::string("../../rig.yaml"),
                                  std::string("../queue.sqlite"), std::string("calibrated.sqlite")}) {
    const auto reply = client.Post("/api/v1/runs", {{"name", "c.yaml"}, {"recipe", with_out_rig(path)}});
    EXPECT_EQ(reply.http_status, 400) << path << ": " << reply.body.dump();
  }
  const auto inside = client.Post("/api/v1/dry-run", {{"name", "c.yaml"}, {"recipe", with_out_rig("calibrated.yaml")}});
  EXPECT_EQ(inside.http_status, 200) << inside.body.dump();
  EXPECT_TRUE(client.Get("/api/v1/runs").body["runs"].empty());
}

TEST_F(Hardening, AValidTokenIsAcceptedUnderAnyHost) {
  StartDaemon(kToken);
  httplib::Client raw = Raw();
  EXPECT_EQ(raw.Get("/api/v1/health", {{"Host", "rig.lab.example"}})->status, 401);
  raw.set_bearer_token_auth(kToken);
  EXPECT_EQ(raw.Get("/api/v1/health", {{"Host", "rig.lab.example"}})->status, 200);
  EXPECT_EQ(raw.Post("/api/v1/dry-run", json{{"recipe", SmallRecipeYaml()}}.dump(), "text/plain")->status, 415);
}

// Finding 6: a chunked body was read whole before the size limit applied.
TEST_F(Hardening, AChunkedUploadIsRefusedBeforeItsBodyIsRead) {
  StartDaemon();
  RawConnection connection(served_->port());
  ASSERT_TRUE(connection.connected());
  // Headers only: the answer must come without a byte of the body.
  ASSERT_TRUE(connection.Send("POST /api/v1/dry-run HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
                              "Transfer-Encoding: chunked\r\n\r\n"));
  EXPECT_EQ(connection.ReadStatus(), 411);

  // Through a client that streams 8 MiB: refused, and the daemon serves on.
  httplib::Client raw = Raw();
  const std::string piece(64 * 1024, 'x');
  const auto reply = raw.Post(
      "/api/v1/dry-run",
      [&, sent = std::size_t{0}](std::size_t, httplib::DataSink& sink) mutable {
        if (sent >= 8u << 20) {
          sink.done();
          return true;
        }
        sent += piece.size();
        return sink.write(piece.data(), piece.size());
      },
      "application/json");
  if (reply) {
    EXPECT_EQ(reply->status, 411);  // or the connection closed while sending: either way not read
  }
  // A body with a length above the limit: 413 as before.
  const auto large = raw.Post("/api/v1/dry-run", std::string(128 * 1024, ' '), "application/json");
  ASSERT_TRUE(large);
  EXPECT_EQ(large->status, 413);
  EXPECT_EQ(Client().Get("/api/v1/health").http_status, 200);
}

// Finding 5: eight event streams or eight slow clients took every worker.
TEST_F(Hardening, HealthAnswersWhileStreamsAndSlowClientsHoldConnections) {
  StartDaemon();
  ApiClient client = Client();
  // A paused run keeps a second one queued, so streams on the second stay open.
  const auto first = client.Post("/api/v1/runs", {{"recipe", SmallRecipeYaml("", 1000)}});
  ASSERT_EQ(first.http_status, 201);
  const std::string running = first.body["id"];
  bool paused = false;
  client.FollowEvents(running, [&](const std::string& type, const json& data) {
    if (type == "state" && data["state"] == "running") {
      EXPECT_EQ(Client().Post("/api/v1/runs/" + running + "/pause", json::object()).http_status, 202);
    }
    if (type == "state" && data["state"] == "paused") paused = true;
    return !paused;
  });
  ASSERT_TRUE(paused);
  const auto second = client.Post("/api/v1/runs", {{"recipe", SmallRecipeYaml()}});
  ASSERT_EQ(second.http_status, 201);
  const std::string queued = second.body["id"];

  // Streams up to the cap of 12 (the one followed above may not have closed
  // on the server's side yet), then 503.
  std::vector<std::unique_ptr<RawConnection>> held;
  int streams = 0, refused = 0;
  while (refused == 0 && streams <= 12) {
    held.push_back(std::make_unique<RawConnection>(served_->port()));
    ASSERT_TRUE(held.back()->Send("GET /api/v1/runs/" + queued + "/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"));
    const int status = held.back()->ReadStatus();
    streams += status == 200;
    refused += status == 503;
    ASSERT_TRUE(status == 200 || status == 503) << status;
  }
  EXPECT_GE(streams, 11);
  EXPECT_EQ(refused, 1);
  for (int i = 0; i < 9; ++i) {  // clients that never finish their headers
    held.push_back(std::make_unique<RawConnection>(served_->port()));
    ASSERT_TRUE(held.back()->Send("GET /api/v1/health HTTP/1.1\r\nHo"));
  }
  for (int i = 0; i < 3; ++i) {
    const auto health = Client().Get("/api/v1/health");
    EXPECT_EQ(health.http_status, 200) << health.body.dump();
  }
  held.clear();
  EXPECT_EQ(client.Post("/api/v1/runs/" + running + "/abort", json::object()).http_status, 202);
}

// Opens event streams with `request` until one is refused (503), keeping
// the accepted ones open in *streams; at most `most` are expected.
void HoldEveryStreamSlot(int port, const std::string& request, std::size_t most,
                         std::vector<std::unique_ptr<RawConnection>>* streams) {
  for (int refused = 0; refused == 0;) {
    ASSERT_LE(streams->size(), most);
    auto stream = std::make_unique<RawConnection>(port);
    ASSERT_TRUE(stream->Send(request));
    const int status = stream->ReadStatus();
    ASSERT_TRUE(status == 200 || status == 503) << status;
    if (status == 503) ++refused;
    else streams->push_back(std::move(stream));
  }
}

// Starts a long run and pauses it once running: streams on it stay open.
std::string PausedRun(ApiClient& client, const std::function<ApiClient()>& another) {
  const auto submitted = client.Post("/api/v1/runs", {{"recipe", SmallRecipeYaml("", 1000)}});
  EXPECT_EQ(submitted.http_status, 201) << submitted.body.dump();
  const std::string id = submitted.body.value("id", "");
  bool paused = false;
  client.FollowEvents(id, [&](const std::string& type, const json& data) {
    if (type == "state" && data["state"] == "running") {
      EXPECT_EQ(another().Post("/api/v1/runs/" + id + "/pause", json::object()).http_status, 202);
    }
    if (type == "state" && data["state"] == "paused") paused = true;
    return !paused;
  });
  EXPECT_TRUE(paused);
  return id;
}

// #39.1: the Host test was a "127." prefix, so a rebinding name such as
// 127.0.0.1.rebind.attacker.example passed, and its matching Origin too.
TEST_F(Hardening, RebindingHostsAndTheirOriginsChangeNothing) {
  StartDaemon("", nullptr, [](ApiOptions& api) { api.allowed_hosts = {"rig.lab.example"}; });
  ApiClient client = Client();
  const std::string id = PausedRun(client, [this] { return Client(); });
  const std::string port = std::to_string(served_->port());
  const std::string body = json{{"recipe", SmallRecipeYaml()}}.dump();
  httplib::Client raw = Raw();
  for (const std::string host : {"127.0.0.1.rebind.attacker.example", "127.attacker.example", "127.0.0.1.",
                                 "localhost.attacker.example", "0x7f.0.0.1", "127.1", "rig.lab.example.attacker.example"}) {
    const httplib::Headers as_page = {{"Host", host + ":" + port}, {"Origin", "http://" + host + ":" + port}};
    EXPECT_EQ(raw.Get("/api/v1/runs", as_page)->status, 403) << host;
    EXPECT_EQ(raw.Get("/api/v1/runs/" + id + "/files/journal.jsonl", as_page)->status, 403) << host;
    EXPECT_EQ(raw.Post("/api/v1/runs", as_page, body, "application/json")->status, 403) << host;
    EXPECT_EQ(raw.Post("/api/v1/runs/" + id + "/abort", as_page, "{}", "application/json")->status, 403) << host;
    EXPECT_EQ(raw.Post("/api/v1/runs/" + id + "/resume", as_page, "{}", "application/json")->status, 403) << host;
    // The rebinding page's Origin with the daemon's own Host: refused as well.
    const httplib::Headers origin_only = {{"Origin", "http://" + host + ":" + port}};
    EXPECT_EQ(raw.Get("/api/v1/runs", origin_only)->status, 403) << host;
    EXPECT_EQ(raw.Post("/api/v1/runs/" + id + "/abort", origin_only, "{}", "application/json")->status, 403) << host;
  }
  // Nothing changed: one run, still paused.
  const auto runs = client.Get("/api/v1/runs");
  ASSERT_EQ(runs.body["runs"].size(), 1u) << runs.body.dump();
  EXPECT_EQ(runs.body["runs"][0]["state"], "paused");

  // Loopback literals, localhost and the allowed name are served.
  for (const std::string host : {"127.0.0.1", "127.0.0.2", "127.255.255.254", "[::1]", "localhost", "LocalHost",
                                 "rig.lab.example"}) {
    const httplib::Headers as_page = {{"Host", host + ":" + port}, {"Origin", "http://" + host + ":" + port}};
    EXPECT_EQ(raw.Get("/api/v1/runs", as_page)->status, 200) << host;
  }
  const httplib::Headers allowed = {{"Host", "rig.lab.example:" + port}, {"Origin", "http://rig.lab.example:" + port}};
  EXPECT_EQ(raw.Post("/api/v1/runs/" + id + "/abort", allowed, "{}", "application/json")->status, 202);
}

// Requests that cannot be met get the status that says why and a message
// that names the field or state, never the JSON library's words or the
// daemon's own paths; a request that would change nothing is refused.
TEST_F(Hardening, RequestsThatCannotBeMetSayWhyWithTheRightStatus) {
  StartDaemon();
  ApiClient client = Client();
  httplib::Client raw = Raw();
  auto error_of = [](const httplib::Result& result) {
    return json::parse(result->body, nullptr, false).value("error", std::string("(not JSON) ") + result->body);
  };
  // A route asked with a method it does not take.
  auto expect_405 = [](const httplib::Result& result, const std::string& allow) {
    ASSERT_TRUE(result);
    EXPECT_EQ(result->status, 405) << result->body;
    EXPECT_EQ(result->get_header_value("Allow"), allow);
  };
  expect_405(raw.Post("/api/v1/health", "{}", "application/json"), "GET");
  expect_405(raw.Get("/api/v1/dry-run"), "POST");
  expect_405(raw.Delete("/api/v1/runs/000001-x"), "GET");
  expect_405(raw.Put("/api/v1/runs", "{}", "application/json"), "GET, POST");
  // A JSON body of the wrong shape names the field.
  const auto array = raw.Post("/api/v1/dry-run", "[\"recipe\"]", "application/json");
  EXPECT_EQ(array->status, 400);
  EXPECT_NE(error_of(array).find("not a JSON object"), std::string::npos) << array->body;
  const auto number = raw.Post("/api/v1/dry-run", json{{"recipe", SmallRecipeYaml()}, {"name", 7}}.dump(), "application/json");
  EXPECT_EQ(number->status, 400);
  EXPECT_NE(error_of(number).find("'name' must be a string"), std::string::npos) << number->body;
  EXPECT_EQ(array->body.find("json.exception"), std::string::npos) << array->body;
  EXPECT_EQ(number->body.find("json.exception"), std::string::npos) << number->body;
  const auto relative = raw.Post("/api/v1/dry-run", json{{"recipe", SmallRecipeYaml()}, {"path", "r/x.yaml"}}.dump(),
                                 "application/json");
  EXPECT_EQ(relative->status, 400);
  EXPECT_NE(error_of(relative).find("must be absolute"), std::string::npos) << relative->body;
  // Media types are case-insensitive.
  EXPECT_EQ(raw.Post("/api/v1/dry-run", json{{"recipe", SmallRecipeYaml()}}.dump(), "Application/JSON")->status, 200);

  // Pause, resume and abort only where they change something.
  const std::string id = PausedRun(client, [this] { return Client(); });
  const std::string run = "/api/v1/runs/" + id;
  const auto again = client.Post(run + "/pause", json::object());
  EXPECT_EQ(again.http_status, 409);
  EXPECT_NE(again.body.value("error", "").find("already paused"), std::string::npos) << again.body.dump();
  // Each acknowledgement is the run's record and what was asked of it.
  const auto resumed = client.Post(run + "/resume", json::object());
  EXPECT_EQ(resumed.http_status, 202);
  EXPECT_EQ(resumed.body["id"], id);
  EXPECT_EQ(resumed.body["requested"], "resume");
  EXPECT_TRUE(resumed.body.contains("state")) << resumed.body.dump();
  const auto twice = client.Post(run + "/resume", json::object());
  EXPECT_EQ(twice.http_status, 409);
  EXPECT_NE(twice.body.value("error", "").find("not paused"), std::string::npos) << twice.body.dump();
  EXPECT_EQ(client.Post("/api/v1/runs/000099-none/pause", json::object()).http_status, 404);

  // A stream's id must be one; a damaged image is the request's problem, said
  // with the run's own file name.
  EXPECT_EQ(raw.Get(run + "/events", {{"Last-Event-ID", "-1"}})->status, 400);
  std::ofstream(fs::path(dir_.path()) / "data" / "runs" / id / "torn.png") << "not a png";
  const auto torn = raw.Get(run + "/preview/torn.png");
  EXPECT_EQ(torn->status, 400) << torn->body;
  EXPECT_NE(error_of(torn).find("'torn.png' in the run cannot be shown"), std::string::npos) << torn->body;
  EXPECT_EQ(torn->body.find((dir_.path() / "data").string()), std::string::npos) << torn->body;

  // Query values out of range or out of order, each named with what was given.
  const std::string image = "ground_truth/albedo.tiff";  // the simulated rig's: the run is paused before its first frame
  const std::pair<std::string, std::string> refusals[] = {
      {"?low=5&high=2", "?low= must be below ?high=, got 5 and 2"},
      {"?gamma=0", "?gamma= must be > 0, got '0'"},
      {"?max_side=8", "?max_side= must be within [16, 8192], got '8'"}};
  for (const auto& [query, message] : refusals) {
    const auto refused = raw.Get(run + "/preview/" + image + query);
    EXPECT_EQ(refused->status, 400) << query;
    EXPECT_NE(error_of(refused).find(message), std::string::npos) << query << ": " << refused->body;
  }
  EXPECT_EQ(raw.Get(run + "/preview/" + image + "?low=5")->status, 200);  // a default high below it widens
  for (const char* limit : {"0", "-5", "2.5"}) {
    const auto listed = raw.Get(std::string("/api/v1/runs?limit=") + limit);
    EXPECT_EQ(listed->status, 400) << limit;
    EXPECT_NE(error_of(listed).find(std::string("?limit= must be a whole number within [1, 1000], got '") + limit + "'"),
              std::string::npos)
        << listed->body;
  }

  const auto aborting = client.Post(run + "/abort", json::object());
  EXPECT_EQ(aborting.http_status, 202);
  EXPECT_EQ(aborting.body["id"], id);
  EXPECT_EQ(aborting.body["requested"], "abort");
  EXPECT_EQ(client.Post(run + "/abort", json::object()).http_status, 409);
}

TEST(LoopbackAddress, OnlyLoopbackLiteralsAndLocalhost) {
  for (const char* yes : {"127.0.0.1", "127.1.2.3", "::1", "0:0:0:0:0:0:0:1", "localhost", "LOCALHOST"})
    EXPECT_TRUE(IsLoopbackAddress(yes)) << yes;
  for (const char* no : {"127.0.0.1.attacker.example", "127.", "127.1", "0177.0.0.1", "128.0.0.1", "10.0.0.1", "::2",
                         "localhost.", "localhost.attacker.example", "", "0.0.0.0"})
    EXPECT_FALSE(IsLoopbackAddress(no)) << no;
}

// #39.2: an abandoned stream kept its slot until the next keepalive write (~15 s).
TEST_F(Hardening, ClosedStreamsFreeTheirSlotsWithinASecond) {
  StartDaemon("", nullptr, [](ApiOptions& api) {
    api.max_event_streams = 32;
    api.worker_threads = 40;
  });
  ApiClient client = Client();
  const std::string id = PausedRun(client, [this] { return Client(); });
  const std::string request = "GET /api/v1/runs/" + id + "/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n";
  // Every slot taken (the stream followed above may still be closing on the server's side).
  std::vector<std::unique_ptr<RawConnection>> streams;
  ASSERT_NO_FATAL_FAILURE(HoldEveryStreamSlot(served_->port(), request, 33, &streams));
  EXPECT_GE(streams.size(), 31u);
  // The watchers go (closed tabs, Ctrl-C): a new one is served within 1 s.
  const std::size_t closed = streams.size();
  streams.clear();
  const auto gone = std::chrono::steady_clock::now();
  int status = 0;
  while (status != 200 && std::chrono::steady_clock::now() - gone < std::chrono::seconds(3)) {
    RawConnection watcher(served_->port());
    ASSERT_TRUE(watcher.Send(request));
    status = watcher.ReadStatus();
    if (status != 200) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  const double waited_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - gone).count();
  EXPECT_EQ(status, 200);
  EXPECT_LT(waited_s, 1.0);
  // Within a second more, every slot is free again.
  std::this_thread::sleep_for(std::chrono::seconds(1));
  for (std::size_t i = 0; i < closed; ++i) {
    streams.push_back(std::make_unique<RawConnection>(served_->port()));
    ASSERT_TRUE(streams.back()->Send(request));
    EXPECT_EQ(streams.back()->ReadStatus(), 200) << i;
  }
  streams.clear();
  EXPECT_EQ(client.Post("/api/v1/runs/" + id + "/abort", json::object()).http_status, 202);
}

// #39.2: `photorig watch` and `submit --watch` exited 3 when every stream
// slot was taken, while the run went on. They wait the refusal out now, and
// follow the run to its end once a slot is free.
TEST_F(Hardening, AWatcherRefusedForWantOfSlotsReconnectsAndFollowsTheRunToItsEnd) {
  StartDaemon("", nullptr, [](ApiOptions& api) { api.max_event_streams = 2; });
  ApiClient client = Client();
  const std::string id = PausedRun(client, [this] { return Client(); });
  const std::string request = "GET /api/v1/runs/" + id + "/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n";
  std::vector<std::unique_ptr<RawConnection>> streams;
  ASSERT_NO_FATAL_FAILURE(HoldEveryStreamSlot(served_->port(), request, 3, &streams));
  // Without reconnecting, the refusal is the answer.
  const std::string refusal = Client().FollowEvents(id, [](const std::string&, const json&) { return true; });
  EXPECT_NE(refusal.find("too many open event streams"), std::string::npos) << refusal;

  std::mutex seen_mutex;
  std::vector<std::string> seen;
  const auto saw = [&](const std::string& type) {
    std::lock_guard<std::mutex> lock(seen_mutex);
    return std::find(seen.begin(), seen.end(), type) != seen.end();
  };
  std::string error = "not finished";
  std::atomic<bool> finished{false};
  const Reconnect reconnect{100, 10};
  std::thread watcher([&] {
    error = Client().FollowEvents(id, [&](const std::string& type, const json&) {
      std::lock_guard<std::mutex> lock(seen_mutex);
      seen.push_back(type);
      return true;
    }, &reconnect);
    finished = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  EXPECT_FALSE(finished) << "the watcher gave up while every slot was taken: " << error;
  streams.clear();  // the other watchers go: a slot is free within a second
  const auto freed = std::chrono::steady_clock::now();
  while (!saw("state") && !finished &&
         std::chrono::steady_clock::now() - freed < std::chrono::seconds(5))
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_LT(std::chrono::steady_clock::now() - freed, std::chrono::seconds(2));
  EXPECT_EQ(client.Post("/api/v1/runs/" + id + "/abort", json::object()).http_status, 202);
  watcher.join();
  EXPECT_EQ(error, "");
  ASSERT_FALSE(seen.empty());
  EXPECT_EQ(seen.front(), "state");  // the run's history from its first event, once connected
  EXPECT_EQ(seen.back(), "stop");
}

// #39.2: with 64 or 100 slow-header clients /health stopped answering.
TEST_F(Hardening, HealthAnswersWithin100MsUnder200IdleAndSlowConnections) {
  StartDaemon("", nullptr, [](ApiOptions& api) { api.read_timeout_ms = 2000; });
  std::vector<std::unique_ptr<RawConnection>> held;
  for (int i = 0; i < 200; ++i) {
    held.push_back(std::make_unique<RawConnection>(served_->port()));
    ASSERT_TRUE(held.back()->connected()) << i;
    // Half say nothing, half stop in the middle of their headers.
    if (i % 2) {
      ASSERT_TRUE(held.back()->Send("GET /api/v1/health HTTP/1.1\r\nHo"));
    }
  }
  // A trickling client: a byte every 200 ms never completes its headers.
  RawConnection trickle(served_->port());
  ASSERT_TRUE(trickle.Send("GET /api/v1/health HTTP/1.1\r\n"));
  const auto trickle_started = std::chrono::steady_clock::now();
  double slowest_ms = 0;
  for (int i = 0; i < 10; ++i) {
    const auto asked = std::chrono::steady_clock::now();
    const auto health = Client().Get("/api/v1/health");  // a new connection each time
    slowest_ms = std::max(slowest_ms, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - asked).count());
    EXPECT_EQ(health.http_status, 200) << health.body.dump();
    trickle.Send("X");
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  EXPECT_LT(slowest_ms, 100.0);
  // The header timeout runs from the first byte, so the trickle is cut off
  // 2 s after it began (no status: the connection just ends) although it
  // never paused for long.
  timeval wait{4, 0};
  ::setsockopt(trickle.fd(), SOL_SOCKET, SO_RCVTIMEO, &wait, sizeof(wait));
  EXPECT_EQ(trickle.ReadStatus(), 0);
  EXPECT_LT(std::chrono::steady_clock::now() - trickle_started, std::chrono::milliseconds(3000));
}

TEST(ApiOptionsCheck, StreamsMustLeaveWorkersFree) {
  ApiOptions options;
  std::string why;
  EXPECT_TRUE(options.IsValid(&why)) << why;
  options.worker_threads = options.max_event_streams + 7;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("worker_threads"), std::string::npos);
}

}  // namespace
}  // namespace photorig::daemon
