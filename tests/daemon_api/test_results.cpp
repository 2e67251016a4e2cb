// Runs of the real photorigd end in results: the recipe's solve stage runs
// under the daemon, the run record and `photorig submit --watch` report it,
// the files API lists and serves the run (and nothing outside it), `photorig
// fetch` downloads it byte for byte, and a recipe for another rig is refused.

#include "daemon_process.h"
#include "photorig/daemon/service/internal/api_client.h"
#include "photorig/daemon/io/image_io.h"
#include "photorig/daemon/service/run_queue.h"

#include <gtest/gtest.h>
#include <httplib.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <thread>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using photorig::testing::DaemonProcess;
using photorig::testing::ReadText;
using photorig::testing::RunPhotorig;
using photorig::testing::SmallRigYaml;
using photorig::testing::TempDir;

// A dark frame, one frame per listed LED, then Lambertian photometric stereo.
std::string PsRecipe(const std::string& rig, const std::string& leds = "all") {
  return "recipe:\n  name: small-ps\n  rig: " + rig +
         "\ncapture:\n  exposure_us: 1000\n  steps:\n    - dark: {count: 1}\n    - each_led: {leds: " + leds +
         "}\nsolve:\n  - photometric_stereo: {method: lambertian}\n";
}

class Results : public ::testing::Test {
 protected:
  void SetUp() override {
    rig_ = dir_.Write("rig.yaml", SmallRigYaml());
    daemon_ = std::make_unique<DaemonProcess>(dir_.path() / "data", rig_, log_, std::vector<std::string>{});
    port_ = daemon_->WaitReady(log_, 0);
    ASSERT_GT(port_, 0) << ReadText(log_);
  }
  void TearDown() override {
    if (daemon_) {
      EXPECT_EQ(daemon_->Terminate(), 0) << ReadText(log_);
    }
  }
  std::string Url() const { return "http://127.0.0.1:" + std::to_string(port_); }
  ApiClient Client() const {
    ApiClientOptions options;
    options.url = Url();
    options.timeout_s = 20;
    return ApiClient(options);
  }
  // `photorig ARGS --url URL`, its output in `name` under the test folder; the exit code.
  int Photorig(const std::string& args, const std::string& name) {
    return RunPhotorig(args + " --url " + Url(), dir_.path() / name);
  }
  std::string Output(const std::string& name) const { return ReadText(dir_.path() / name); }
  // The run id a `photorig submit` printed.
  std::string SubmittedId(const std::string& name) const {
    std::smatch match;
    const std::string text = Output(name);
    return std::regex_search(text, match, std::regex("submitted ([0-9]{6}-[A-Za-z0-9_-]+):")) ? match[1].str() : "";
  }
  fs::path RunDirectory(const std::string& id) const { return dir_.path() / "data/runs" / id; }

  TempDir dir_;
  fs::path log_ = dir_.path() / "photorigd.log";
  std::string rig_;
  std::unique_ptr<DaemonProcess> daemon_;
  int port_ = 0;
};

TEST_F(Results, SolveStageRunsUnderTheDaemonAndEndsInTheRunRecord) {
  ApiClient client = Client();
  const std::string recipe = PsRecipe("../rig.yaml");
  const auto submitted = client.Post(
      "/api/v1/runs", {{"name", "small-ps.yaml"}, {"recipe", recipe}, {"path", (dir_.path() / "recipes/small-ps.yaml").string()}});
  ASSERT_EQ(submitted.http_status, 201) << submitted.body.dump();
  const std::string id = submitted.body["id"];
  std::vector<std::string> types;
  std::vector<std::string> states;
  json finished, stop;
  EXPECT_EQ(client.FollowEvents(id,
                                [&](const std::string& type, const json& data) {
                                  types.push_back(type);
                                  if (type == "state") states.push_back(data["state"]);
                                  if (type == "solve_finished") finished = data;
                                  if (type == "stop") stop = data;
                                  return true;
                                }),
            "");
  // frames, then the solving state and the stage's start and end, then done.
  const auto at = [&types](const std::string& type) { return std::find(types.begin(), types.end(), type) - types.begin(); };
  EXPECT_LT(at("frame"), at("solve_started"));
  EXPECT_LT(at("solve_started"), at("solve_progress"));  // the solver's own reports, relayed
  EXPECT_LT(at("solve_progress"), at("solve_finished"));
  EXPECT_LT(at("solve_finished"), at("stop"));
  EXPECT_NE(std::find(states.begin(), states.end(), "solving"), states.end());
  EXPECT_EQ(finished["stage"], "photometric_stereo");
  EXPECT_EQ(finished["termination"], "success") << finished.dump();

  const json run = client.Get("/api/v1/runs/" + id).body;
  EXPECT_EQ(run["state"], "done") << run.dump();
  ASSERT_TRUE(run.contains("solve")) << run.dump();
  EXPECT_EQ(run["solve"]["ok"], true);
  const json& stage = run["solve"]["stages"][0];
  EXPECT_EQ(stage["stage"], "photometric_stereo");
  EXPECT_EQ(stage["results"], "results/ps");
  EXPECT_GT(stage["figures"]["pixels_solved"].get<int>(), 100);
  EXPECT_GT(stage["timings_ms"]["total"].get<double>(), 0.0);
  EXPECT_EQ(run["results"]["path"], "runs/" + id + "/results");
  EXPECT_EQ(run["results"]["url"], "/api/v1/runs/" + id + "/files?under=results");
  EXPECT_EQ(stop["solve"], run["solve"]);
  EXPECT_EQ(stop["results"], run["results"]);

  // The results as listed are the files on disk, and download as they are.
  const auto listing = client.Get(run["results"]["url"].get<std::string>());
  ASSERT_EQ(listing.http_status, 200) << listing.body.dump();
  std::set<std::string> listed;
  for (const json& file : listing.body["files"]) {
    const std::string path = file["path"];
    listed.insert(path);
    EXPECT_EQ(path.rfind("results/", 0), 0u) << path;
    EXPECT_EQ(file["size"].get<std::uint64_t>(), fs::file_size(RunDirectory(id) / path)) << path;
  }
  EXPECT_TRUE(listed.count("results/ps/normals.tiff"));
  EXPECT_TRUE(listed.count("results/ps/report.json"));
  std::string bytes;
  ASSERT_EQ(client.Download(id, "results/ps/normals.tiff", &bytes), 200);
  EXPECT_EQ(bytes, ReadText(RunDirectory(id) / "results/ps/normals.tiff"));
  std::set<std::string> all;
  const json everything = client.Get("/api/v1/runs/" + id + "/files").body;
  for (const json& file : everything["files"]) all.insert(file["path"].get<std::string>());
  EXPECT_TRUE(all.count("manifest.json") && all.count("journal.jsonl") && all.count("frames/0001_led00.png"));
  EXPECT_TRUE(std::includes(all.begin(), all.end(), listed.begin(), listed.end()));
}

TEST_F(Results, SubmitWatchPrintsTheSolveAndFetchDownloadsTheRunByteForByte) {
  const std::string recipe = dir_.Write("recipes/small-ps.yaml", PsRecipe("../rig.yaml"));
  ASSERT_EQ(Photorig("submit " + recipe + " --watch", "submit.txt"), 0) << Output("submit.txt");
  const std::string text = Output("submit.txt");
  const std::string id = SubmittedId("submit.txt");
  ASSERT_FALSE(id.empty()) << text;
  // After the frames: the stage's summary and where its results are.
  const std::size_t frames = text.find("frames 5/5");
  ASSERT_NE(frames, std::string::npos) << text;
  EXPECT_NE(text.find("solve photometric_stereo: success", frames), std::string::npos) << text;
  EXPECT_NE(text.find("pixels_solved", frames), std::string::npos) << text;
  EXPECT_NE(text.find("results: runs/" + id + "/results", frames), std::string::npos) << text;

  const fs::path out = dir_.path() / "fetched";
  ASSERT_EQ(Photorig("fetch " + id + " --out " + out.string(), "fetch.txt"), 0) << Output("fetch.txt");
  const json listing = Client().Get("/api/v1/runs/" + id + "/files").body;
  ASSERT_GT(listing["files"].size(), 10u);
  for (const json& file : listing["files"]) {
    const std::string path = file["path"];
    EXPECT_EQ(ReadText(out / path), ReadText(RunDirectory(id) / path)) << path;
  }
  int files_fetched = 0;
  for (const auto& entry : fs::recursive_directory_iterator(out)) files_fetched += entry.is_regular_file();
  EXPECT_EQ(files_fetched, static_cast<int>(listing["files"].size()));  // no temporary file left behind

  // Fetched again, intact files are kept; a damaged one is fetched anew.
  std::ofstream(out / "results/ps/report.json", std::ios::app) << "damage";
  ASSERT_EQ(Photorig("fetch " + id + " --out " + out.string(), "again.txt"), 0) << Output("again.txt");
  EXPECT_NE(Output("again.txt").find("1 files fetched, " + std::to_string(files_fetched - 1) + " already present"),
            std::string::npos)
      << Output("again.txt");
  EXPECT_EQ(ReadText(out / "results/ps/report.json"), ReadText(RunDirectory(id) / "results/ps/report.json"));

  // --results: the results folder only.
  const fs::path results = dir_.path() / "results-only";
  ASSERT_EQ(Photorig("fetch " + id + " --results --out " + results.string(), "results.txt"), 0) << Output("results.txt");
  for (const auto& entry : fs::recursive_directory_iterator(results)) {
    if (!entry.is_regular_file()) continue;
    EXPECT_EQ(*fs::relative(entry.path(), results).begin(), "results") << entry.path();
  }
  EXPECT_EQ(ReadText(results / "results/ps/normals.tiff"), ReadText(RunDirectory(id) / "results/ps/normals.tiff"));

  EXPECT_EQ(Photorig("fetch 000999-nothing --out " + results.string(), "unknown.txt"), 2) << Output("unknown.txt");
  EXPECT_EQ(RunPhotorig("fetch " + id + " --url http://127.0.0.1:1", dir_.path() / "closed.txt"), 3)
      << Output("closed.txt");
}

TEST_F(Results, UnusableSolveFailsTheRunAndSubmitWatchExitsOne) {
  // Two lights cannot determine a normal: the solver reports no usable result.
  const std::string recipe = dir_.Write("recipes/two-leds.yaml", PsRecipe("../rig.yaml", "[0, 1]"));
  EXPECT_EQ(Photorig("submit " + recipe + " --watch", "submit.txt"), 1) << Output("submit.txt");
  const std::string id = SubmittedId("submit.txt");
  ASSERT_FALSE(id.empty()) << Output("submit.txt");
  const json run = Client().Get("/api/v1/runs/" + id).body;
  EXPECT_EQ(run["state"], "failed") << run.dump();
  EXPECT_EQ(run["reason"].get<std::string>().rfind("photometric_stereo: ", 0), 0u) << run.dump();
  EXPECT_EQ(run["solve"]["ok"], false);
  EXPECT_EQ(run["solve"]["stages"][0]["ok"], false);
  EXPECT_EQ(run["stop"]["status"], "complete");  // the capture itself was sound
  EXPECT_NE(Output("submit.txt").find("stopped: failed - photometric_stereo: "), std::string::npos)
      << Output("submit.txt");
}

// The queue as a crash during the solve leaves it: the run still solving,
// its results folder half written. The next start solves again from the frames.
TEST_F(Results, ARunInterruptedWhileSolvingSolvesAgainAtTheNextStart) {
  const auto submitted = Client().Post("/api/v1/runs", {{"recipe", PsRecipe("rig.yaml")}});
  ASSERT_EQ(submitted.http_status, 201) << submitted.body.dump();
  const std::string id = submitted.body["id"];
  EXPECT_EQ(Client().FollowEvents(id, [](const std::string&, const json&) { return true; }), "");
  ASSERT_EQ(daemon_->Terminate(), 0);
  {
    RunQueue queue((dir_.path() / "data/queue.sqlite").string());
    QueuedRun run = *queue.Get(id);
    run.state = RunState::kSolving;
    run.solve = nullptr;
    queue.Update(run);
  }
  std::ofstream(RunDirectory(id) / "results/ps/left-over.tiff") << "from the interrupted solve";

  daemon_ = std::make_unique<DaemonProcess>(dir_.path() / "data", rig_, log_, std::vector<std::string>{});
  port_ = daemon_->WaitReady(log_, 1);
  ASSERT_GT(port_, 0) << ReadText(log_);
  json stop;
  EXPECT_EQ(Client().FollowEvents(id,
                                  [&](const std::string& type, const json& data) {
                                    if (type == "stop") stop = data;
                                    return true;
                                  }),
            "");
  EXPECT_EQ(stop["state"], "done") << stop.dump() << ReadText(log_);
  EXPECT_EQ(stop["solve"]["ok"], true) << stop.dump();
  EXPECT_FALSE(fs::exists(RunDirectory(id) / "results/ps/left-over.tiff"));
  EXPECT_TRUE(fs::exists(RunDirectory(id) / "results/ps/normals.tiff"));
}

TEST_F(Results, SubmitWatchJsonExitsZeroForADoneRun) {
  const std::string recipe = dir_.Write("recipes/small-ps.yaml", PsRecipe("../rig.yaml"));
  EXPECT_EQ(Photorig("submit " + recipe + " --watch --json", "submit.json"), 0) << Output("submit.json");
}

TEST_F(Results, FilesOutsideTheRunDirectoryAreRefused) {
  ApiClient client = Client();
  const auto submitted = client.Post("/api/v1/runs", {{"recipe", PsRecipe("rig.yaml")}});
  ASSERT_EQ(submitted.http_status, 201) << submitted.body.dump();
  const std::string id = submitted.body["id"];
  EXPECT_EQ(client.FollowEvents(id, [](const std::string&, const json&) { return true; }), "");
  // Links planted in the run that lead out of it.
  const fs::path run = RunDirectory(id);
  fs::create_directory_symlink(dir_.path(), run / "results/outside");
  fs::create_symlink(rig_, run / "results/rig-link.yaml");

  std::string bytes;
  for (const std::string path : {"../../queue.sqlite", "frames/../../../rig.yaml", "%2e%2e/%2e%2e/queue.sqlite",
                                 "/etc/passwd", "results/outside/rig.yaml", "results/rig-link.yaml"})
    EXPECT_EQ(client.Download(id, path, &bytes), 400) << path << ": " << bytes;
  EXPECT_EQ(client.Download(id, "results/ps/nothing.tiff", &bytes), 404);
  EXPECT_EQ(client.Download("000999-nothing", "manifest.json", &bytes), 404);
  EXPECT_EQ(client.Get("/api/v1/runs/" + id + "/files?under=../..").http_status, 400);
  EXPECT_EQ(client.Get("/api/v1/runs/" + id + "/files?under=results/outside").http_status, 400);
  // Listings leave symlinks out.
  const json listing = client.Get("/api/v1/runs/" + id + "/files").body;
  ASSERT_FALSE(listing["files"].empty());
  for (const json& file : listing["files"])
    EXPECT_EQ(file["path"].get<std::string>().find("results/outside"), std::string::npos) << file.dump();
  EXPECT_EQ(client.Download(id, "manifest.json", &bytes), 200);
}

TEST_F(Results, RecipeForAnotherOrAMissingRigIsRefused) {
  dir_.Write("other.yaml", std::regex_replace(SmallRigYaml(), std::regex("name: small-dome"), "name: other-dome"));
  const std::string other = dir_.Write("recipes/other.yaml", PsRecipe("../other.yaml"));
  EXPECT_EQ(Photorig("submit " + other, "other.txt"), 2) << Output("other.txt");
  EXPECT_NE(Output("other.txt").find("names rig 'other-dome'"), std::string::npos) << Output("other.txt");
  EXPECT_NE(Output("other.txt").find("this daemon drives rig 'small-dome'"), std::string::npos) << Output("other.txt");
  const std::string missing = dir_.Write("recipes/missing.yaml", PsRecipe("../missing.yaml"));
  EXPECT_EQ(Photorig("submit " + missing, "missing.txt"), 2) << Output("missing.txt");
  EXPECT_NE(Output("missing.txt").find("which does not exist"), std::string::npos) << Output("missing.txt");

  // Over the API, submit and dry-run alike; without the recipe's path only the rig file's name is known.
  ApiClient client = Client();
  const auto refused = client.Post("/api/v1/dry-run", {{"name", "other.yaml"},
                                                       {"recipe", PsRecipe("../other.yaml")},
                                                       {"path", other}});
  EXPECT_EQ(refused.http_status, 422) << refused.body.dump();
  EXPECT_EQ(refused.body["rig"], "small-dome");
  EXPECT_EQ(client.Post("/api/v1/runs", {{"name", "x.yaml"}, {"recipe", PsRecipe("../rigs/sim-gonio.yaml")}}).http_status,
            422);
  EXPECT_EQ(client.Post("/api/v1/dry-run", {{"name", "x.yaml"}, {"recipe", PsRecipe("elsewhere/rig.yaml")}}).http_status,
            200);
  EXPECT_EQ(client.Post("/api/v1/dry-run", {{"name", "x.yaml"}, {"recipe", PsRecipe("small-dome.yaml")}}).http_status,
            200);
  EXPECT_TRUE(client.Get("/api/v1/runs").body["runs"].empty());
}

// A listing that names a file and a folder alike (no run directory can hold
// both; a damaged or foreign server can list them): the file is reported,
// every other file is fetched, and the fetch exits 1 instead of aborting.
TEST(Fetch, AFileAndAFolderOfOneNameAreReportedAndTheRestFetched) {
  TempDir dir;
  const std::map<std::string, std::string> files = {{"frames/0000_dark.png", "first"},
                                                    {"results", "a file named as the folder"},
                                                    {"results/report.json", "second"}};
  httplib::Server server;
  server.Get("/api/v1/runs/000001-x", [](const httplib::Request&, httplib::Response& res) {
    res.set_content(R"({"id": "000001-x", "state": "done"})", "application/json");
  });
  server.Get("/api/v1/runs/000001-x/files", [&](const httplib::Request&, httplib::Response& res) {
    json listing = {{"id", "000001-x"}, {"under", ""}, {"files", json::array()}, {"bytes", 0}};
    for (const auto& [path, bytes] : files)
      listing["files"].push_back({{"path", path}, {"size", bytes.size()}, {"crc32", Crc32(bytes.data(), bytes.size())}});
    res.set_content(listing.dump(), "application/json");
  });
  server.Get(R"(/api/v1/runs/000001-x/files/(.+))", [&](const httplib::Request& req, httplib::Response& res) {
    const auto file = files.find(req.matches[1]);
    if (file == files.end()) res.status = 404;
    else res.set_content(file->second, "application/octet-stream");
  });
  const int port = server.bind_to_any_port("127.0.0.1");
  ASSERT_GT(port, 0);
  // bind_to_any_port already listens: a request before the thread accepts waits in the backlog.
  std::thread serving([&server] { server.listen_after_bind(); });
  const fs::path out = dir.path() / "out";
  const int exit_code = RunPhotorig("fetch 000001-x --json --out " + out.string() + " --url http://127.0.0.1:" +
                                        std::to_string(port),
                                    dir.path() / "fetch.log");
  server.stop();
  serving.join();
  const std::string log = ReadText(dir.path() / "fetch.log");
  EXPECT_EQ(exit_code, 1) << log;
  EXPECT_NE(log.find("both a file and a folder named 'results'"), std::string::npos) << log;
  EXPECT_EQ(ReadText(out / "frames/0000_dark.png"), "first");
  EXPECT_EQ(ReadText(out / "results/report.json"), "second");
  EXPECT_TRUE(fs::is_directory(out / "results"));
}

}  // namespace
}  // namespace photorig::daemon
