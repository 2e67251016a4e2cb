// The API under hostile or careless clients: recipes that expand without
// bound, bytes that are not UTF-8, requests from other web origins, chunked
// uploads, and many slow or long-lived connections.

#include "photorig/daemon/api_client.h"
#include "photorig/daemon/api_server.h"
#include "photorig/daemon/run_queue.h"
#include "served_api.h"
#include "test_support.h"

#include <gtest/gtest.h>
#include <httplib.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <filesystem>
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
  void StartDaemon(const std::string& token = "", const std::function<void(const std::string&)>& before = nullptr) {
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
