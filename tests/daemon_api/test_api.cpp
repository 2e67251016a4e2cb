// The photorigd API over loopback: an in-process service and server on a free
// port, driven with the same client the CLI uses.

#include "photorig/daemon/service/internal/api_client.h"
#include "photorig/daemon/service/api_server.h"
#include "photorig/daemon/capture/run_store.h"
#include "served_api.h"
#include "test_support.h"

#include <gtest/gtest.h>
#include <httplib.h>

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

class Api : public ::testing::Test {
 protected:
  void StartDaemon(const std::string& token, const std::string& faults = "") {
    ServiceOptions options;
    options.data_root = (dir_.path() / "data").string();
    options.rig_path = dir_.Write("rig.yaml", SmallRigYaml(faults));
    options.solve = false;
    options.retry.initial_backoff_ms = 1;
    options.retry.max_backoff_ms = 4;
    ApiOptions api;
    api.port = 0;
    api.token = token;
    api.max_body_bytes = 64 * 1024;
    served_ = std::make_unique<ServedApi>(options, api);
  }
  ApiClient Client(const std::string& token = "") { return served_->Client(token); }
  // Follows the events of `id` to its end; returns the stop event.
  json WaitForStop(ApiClient& client, const std::string& id, std::vector<std::string>* types = nullptr) {
    json stop;
    const std::string error = client.FollowEvents(id, [&](const std::string& type, const json& data) {
      if (types) types->push_back(type);
      if (type == "stop") stop = data;
      return true;
    });
    EXPECT_EQ(error, "");
    return stop;
  }

  TempDir dir_;
  std::unique_ptr<ServedApi> served_;
};

TEST_F(Api, SubmitWatchAndFetchAFrame) {
  StartDaemon("");
  ApiClient client = Client();
  EXPECT_EQ(client.Get("/api/v1/health").body["status"], "ok");
  const auto devices = client.Get("/api/v1/devices");
  ASSERT_EQ(devices.http_status, 200);
  EXPECT_EQ(devices.body["devices"][0]["id"], "small-dome");

  const auto submitted = client.Post("/api/v1/runs", {{"name", "small.yaml"}, {"recipe", SmallRecipeYaml()}});
  ASSERT_EQ(submitted.http_status, 201) << submitted.body.dump();
  const std::string id = submitted.body["id"];
  EXPECT_EQ(submitted.body["plan"]["frames"], 5);
  std::vector<std::string> types;
  const json stop = WaitForStop(client, id, &types);
  EXPECT_EQ(stop["state"], "done") << stop.dump();
  EXPECT_EQ(stop["frames"], 5);
  EXPECT_EQ(std::count(types.begin(), types.end(), "frame"), 5);

  const auto run = client.Get("/api/v1/runs/" + id);
  EXPECT_EQ(run.body["state"], "done");
  EXPECT_EQ(run.body["stop"]["status"], "complete");
  EXPECT_EQ(client.Get("/api/v1/runs").body["runs"].size(), 1u);

  // The frame over HTTP is byte for byte the file on disk.
  std::string bytes;
  ASSERT_EQ(client.Download(id, "frames/0001_led00.png", &bytes), 200);
  const std::string on_disk = photorig::testing::ReadText(dir_.path() / "data/runs" / id / "frames/0001_led00.png");
  EXPECT_EQ(bytes, on_disk);
  EXPECT_TRUE(VerifyRun((dir_.path() / "data/runs" / id).string()).empty());
}

TEST_F(Api, AnErrorQuotingBytesThatAreNotUtf8IsA400WithValidJson) {
  StartDaemon("");
  // The JSON parser's message quotes the bad byte; serialising it used to throw, and the answer became a 500.
  httplib::Client http("127.0.0.1", served_->port());
  const std::string body = "{\"name\": \"x.yaml\", \"recipe\": \"recipe: {name: small}\\ncapture:\\n  steps:\\n    - each_le\xA7" "d: {}\\n\"}";
  const auto res = http.Post("/api/v1/runs", body, "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 400) << res->body;
  const json answer = json::parse(res->body);
  EXPECT_NE(answer.at("error").get<std::string>().find("each_le\xEF\xBF\xBD"), std::string::npos) << res->body;
}

TEST_F(Api, RejectsBadInputWithClear4xx) {
  StartDaemon("");
  ApiClient client = Client();
  // A recipe error names the submitted name, line and column.
  const auto bad = client.Post("/api/v1/runs", {{"name", "mine.yaml"},
                                               {"recipe", "recipe: {name: x}\ncapture:\n  exposure_us: -1\n  steps: []\n"}});
  EXPECT_EQ(bad.http_status, 400);
  EXPECT_NE(bad.body["error"].get<std::string>().find("mine.yaml:3:16: capture.exposure_us"), std::string::npos)
      << bad.body.dump();
  EXPECT_EQ(client.Post("/api/v1/runs", {{"nope", 1}}).http_status, 400);
  EXPECT_EQ(client.Post("/api/v1/runs", {{"recipe", std::string(100 * 1024, '#')}}).http_status, 413);
  EXPECT_EQ(client.Get("/api/v1/runs/000001-nothing").http_status, 404);
  EXPECT_EQ(client.Post("/api/v1/runs/000001-nothing/pause", json::object()).http_status, 404);

  const auto submitted = client.Post("/api/v1/runs", {{"recipe", SmallRecipeYaml()}});
  ASSERT_EQ(submitted.http_status, 201);
  const std::string id = submitted.body["id"];
  WaitForStop(client, id);
  std::string bytes;
  EXPECT_EQ(client.Download(id, "../../queue.sqlite", &bytes), 400);
  EXPECT_EQ(client.Download(id, "frames/../../../rig.yaml", &bytes), 400);
  EXPECT_EQ(client.Download(id, "frames/nope.png", &bytes), 404);
  EXPECT_EQ(client.Download(id, "manifest.json", &bytes), 200);
  EXPECT_EQ(client.Post("/api/v1/runs/" + id + "/abort", json::object()).http_status, 409);  // already done
}

TEST_F(Api, TokenIsRequiredWhenConfigured) {
  StartDaemon(kToken);
  EXPECT_EQ(Client().Get("/api/v1/health").http_status, 401);
  EXPECT_EQ(Client("wrong-token-of-the-same-size-xxxx").Get("/api/v1/runs").http_status, 401);
  EXPECT_EQ(Client(kToken).Get("/api/v1/health").http_status, 200);
  std::string why;
  ApiOptions open;
  open.bind_address = "0.0.0.0";
  EXPECT_FALSE(open.IsValid(&why));
  EXPECT_NE(why.find("requires a bearer token"), std::string::npos);
}

TEST_F(Api, PauseResumeAndAbortARunningRun) {
  // Every trigger drops for a while: the run sits in retries long enough to steer it.
  StartDaemon("", "{camera: {drop_frames: [1, 2]}}");
  ApiClient client = Client();
  // 124 frames: far more than are taken before the abort, however fast frames are stored.
  const std::string recipe = SmallRecipeYaml("", 120);
  const auto first = client.Post("/api/v1/runs", {{"recipe", recipe}});
  const auto second = client.Post("/api/v1/runs", {{"recipe", recipe}});
  ASSERT_EQ(first.http_status, 201);
  ASSERT_EQ(second.http_status, 201);
  const std::string id = first.body["id"], queued = second.body["id"];
  // Abort the queued one before it starts.
  const auto aborted = client.Post("/api/v1/runs/" + queued + "/abort", json::object());
  EXPECT_EQ(aborted.http_status, 200);
  EXPECT_EQ(aborted.body["state"], "aborted");  // carried out at once: the record says so
  EXPECT_EQ(aborted.body["requested"], "abort");
  EXPECT_EQ(client.Get("/api/v1/runs/" + queued).body["state"], "aborted");

  // Each request follows from an event the previous one caused, never from a
  // frame count: the daemon may be many frames ahead of the event stream.
  bool pause_sent = false, paused = false, resumed = false, abort_sent = false;
  json stop;
  const std::string error = client.FollowEvents(id, [&](const std::string& type, const json& data) {
    ApiClient steer = Client();
    if (type == "frame" && data["frames"] >= 3 && !pause_sent) {
      EXPECT_EQ(steer.Post("/api/v1/runs/" + id + "/pause", json::object()).http_status, 202);
      pause_sent = true;
    }
    if (type == "state" && data["state"] == "paused" && !paused) {
      paused = true;
      EXPECT_EQ(steer.Get("/api/v1/runs/" + id).body["state"], "paused");
      EXPECT_EQ(steer.Post("/api/v1/runs/" + id + "/resume", json::object()).http_status, 202);
    }
    if (type == "state" && data["state"] == "running" && paused) resumed = true;
    if (type == "frame" && resumed && !abort_sent) {
      EXPECT_EQ(steer.Post("/api/v1/runs/" + id + "/abort", json::object()).http_status, 202);
      abort_sent = true;
    }
    if (type == "stop") stop = data;
    return true;
  });
  EXPECT_EQ(error, "");
  EXPECT_TRUE(paused);
  EXPECT_TRUE(resumed);
  EXPECT_EQ(stop["state"], "aborted") << stop.dump();
  EXPECT_GE(stop["retries"].get<int>(), 1);
  EXPECT_EQ(stop["dropped_frames"], 2);
  EXPECT_LT(stop["frames"].get<int>(), 124);
  const std::string run = (dir_.path() / "data/runs" / id).string();
  EXPECT_TRUE(VerifyRun(run).empty());
  EXPECT_EQ(LoadRunManifest(run).stop->status, CaptureStatus::kAborted);
}

}  // namespace
}  // namespace photorig::daemon
