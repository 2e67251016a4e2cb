// A data root on a full filesystem (a small tmpfs, mounted by the test as
// root): the run fails cleanly, no temp file holds space, the daemon keeps
// running, starts while the disk is full and says so on /health, and the run
// gets its stop record and manifest once there is room again. photorigd
// started with no byte free comes up read-only (health 503 "disk full", runs
// listed, submit 507) and takes runs once there is room, without a restart. A solve that
// runs out of space part way fails saying what to do, leaves the frames as
// they were and no partial results, and solves once there is room.

#include "daemon_process.h"
#include "photorig/daemon/service/internal/api_client.h"
#include "photorig/daemon/service/run.h"
#include "photorig/daemon/capture/run_store.h"
#include "photorig/daemon/service/service.h"
#include "test_support.h"

#include <gtest/gtest.h>

#include <sys/mount.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <cmath>
#include <thread>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using photorig::testing::Photorig;
using photorig::testing::ReadText;
using photorig::testing::SmallRecipeYaml;
using photorig::testing::SmallRigYaml;
using photorig::testing::TempDir;

class FullDisk : public ::testing::Test {
 protected:
  void SetUp() override {
    data_ = dir_.path() / "data";
    fs::create_directories(data_);
    if (::mount("tmpfs", data_.c_str(), "tmpfs", 0, "size=16m") != 0)
      GTEST_SKIP() << "cannot mount a tmpfs to fill (needs root): " << std::strerror(errno);
    mounted_ = true;
    options_.data_root = data_.string();
    options_.rig_path = dir_.Write("rig.yaml", SmallRigYaml());
    options_.solve = false;
  }
  void TearDown() override {
    if (mounted_) ::umount2(data_.c_str(), MNT_DETACH);
  }
  // Writes until the filesystem refuses; then, given `leave_bytes`, frees that much.
  void Fill(std::uintmax_t leave_bytes = 0) {
    {
      std::ofstream filler(data_ / "filler", std::ios::binary);
      const std::string block(4096, 'x');
      while (filler.write(block.data(), block.size()) && filler.flush()) {
      }
    }
    const std::uintmax_t size = fs::file_size(data_ / "filler");
    fs::resize_file(data_ / "filler", size - std::min(size, leave_bytes));
  }
  // Waits for the run's stop event; returns it.
  static json WaitForStop(const RunService& service, const std::string& id) {
    std::uint64_t seen = 0;
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::minutes(2);  // a hang guard, not a measurement
    while (std::chrono::steady_clock::now() < give_up)
      for (const RunEvent& event : service.EventsAfter(id, seen, 500)) {
        seen = event.seq;
        if (event.type == "stop") return event.data;
      }
    return {};
  }

  TempDir dir_;
  fs::path data_;
  bool mounted_ = false;
  ServiceOptions options_;
};

TEST_F(FullDisk, ARunFailsCleanlyAndTheDaemonStartsAndSaysSo) {
  std::string id;
  {
    RunService service(options_);
    service.Start();
    const ServiceReply submitted = service.Submit("small.yaml", SmallRecipeYaml("", 1000));
    ASSERT_EQ(submitted.http_status, 201) << submitted.body.dump();
    id = submitted.body["id"];
    // Pause after the first frames, fill the disk, go on.
    std::uint64_t seen = 0;
    bool paused = false, pause_sent = false;
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::minutes(2);  // a hang guard, not a measurement
    while (!paused && std::chrono::steady_clock::now() < give_up)
      for (const RunEvent& event : service.EventsAfter(id, seen, 500)) {
        seen = event.seq;
        if (event.type == "frame" && !pause_sent) pause_sent = service.Pause(id).http_status == 202;
        if (event.type == "state" && event.data["state"] == "paused") paused = true;
      }
    ASSERT_TRUE(paused);
    Fill();
    EXPECT_EQ(service.Resume(id).http_status, 202);
    const json stop = WaitForStop(service, id);
    EXPECT_EQ(stop["state"], "failed") << stop.dump();
    EXPECT_NE(stop["reason"].get<std::string>().find("No space left"), std::string::npos) << stop.dump();

    // The daemon serves on and says what is wrong.
    const ServiceReply health = service.Health();
    EXPECT_EQ(health.http_status, 503) << health.body.dump();
    EXPECT_NE(health.body["status"], "ok");
    EXPECT_EQ(service.Submit("small.yaml", SmallRecipeYaml()).http_status, 507);
    EXPECT_EQ(service.GetRun(id).http_status, 200);
    service.Stop();
  }
  for (const auto& entry : fs::recursive_directory_iterator(data_ / "runs"))
    EXPECT_NE(entry.path().extension(), ".tmp") << entry.path();

  {
    // A restart on the full disk: up, and reporting it.
    RunService service(options_);
    service.Start();
    EXPECT_TRUE(service.Healthy());
    EXPECT_EQ(service.Health().http_status, 503);
    EXPECT_EQ(service.ListRuns().http_status, 200);
    service.Stop();
  }

  fs::remove(data_ / "filler");
  {
    // Room again: the run ends with its stop record and manifest, every frame it kept intact.
    RunService service(options_);
    service.Start();
    // Its failure may not have reached the queue: then it resumes from its checkpoint and completes.
    json run = service.GetRun(id).body;
    std::uint64_t seen = 0;
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::minutes(2);  // a hang guard, not a measurement
    while (!IsFinal(RunStateFromName(run["state"].get<std::string>()).value_or(RunState::kQueued)) &&
           std::chrono::steady_clock::now() < give_up) {
      for (const RunEvent& event : service.EventsAfter(id, seen, 500)) seen = event.seq;
      run = service.GetRun(id).body;
    }
    EXPECT_TRUE(run["state"] == "failed" || run["state"] == "done") << run.dump();
    const std::string directory = (data_ / "runs" / id).string();
    ASSERT_TRUE(fs::exists(fs::path(directory) / "manifest.json"));
    const RunManifest manifest = LoadRunManifest(directory);
    ASSERT_TRUE(manifest.stop.has_value());
    EXPECT_NE(manifest.stop->status, CaptureStatus::kRunning);
    EXPECT_GT(manifest.frames.size(), 0u);
    for (const FrameRecord& frame : manifest.frames) EXPECT_NO_THROW(LoadFrame(directory, frame)) << frame.file;
    EXPECT_EQ(service.Health().http_status, 200) << service.Health().body.dump();
    service.Stop();
  }
}

// A client of the daemon once it is ready (its port, from its log); a daemon
// that never gets ready fails the test, and the client reaches nothing.
ApiClient ClientOf(photorig::testing::DaemonProcess& daemon, const fs::path& log) {
  const int port = daemon.WaitReady(log, 0);
  EXPECT_GT(port, 0) << ReadText(log);
  ApiClientOptions client_options;
  client_options.url = "http://127.0.0.1:" + std::to_string(port);
  client_options.timeout_s = 20;
  return ApiClient(client_options);
}

// Submits the small recipe to a daemon that has room again; it must be
// taken, captured whole and stored under `root`, and health must be 200.
void ExpectARunCompletes(ApiClient& client, const fs::path& root, const fs::path& log) {
  const ServiceReply submitted = client.Post("/api/v1/runs", {{"name", "small.yaml"}, {"recipe", SmallRecipeYaml()}});
  ASSERT_EQ(submitted.http_status, 201) << submitted.body.dump() << ReadText(log);
  const std::string id = submitted.body["id"];
  json run;
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::minutes(1);  // a hang guard, not a measurement
  do {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    run = client.Get("/api/v1/runs/" + id).body;
  } while (run.value("state", "") != "done" && run.value("state", "") != "failed" &&
           std::chrono::steady_clock::now() < give_up);
  EXPECT_EQ(run["state"], "done") << run.dump() << ReadText(log);
  EXPECT_EQ(run["frames"], 5);
  EXPECT_TRUE(fs::exists(root / "runs" / id / "manifest.json"));
  const ServiceReply healthy = client.Get("/api/v1/health");
  EXPECT_EQ(healthy.http_status, 200) << healthy.body.dump();
}

TEST_F(FullDisk, PhotorigdStartsReadOnlyWithNoByteFreeAndTakesRunsOnceThereIsRoom) {
  std::string id;
  {
    RunService service(options_);
    service.Start();
    const ServiceReply submitted = service.Submit("small.yaml", SmallRecipeYaml());
    ASSERT_EQ(submitted.http_status, 201) << submitted.body.dump();
    id = submitted.body["id"];
    EXPECT_EQ(WaitForStop(service, id)["state"], "done");
    service.Stop();
  }
  Fill();
  ASSERT_EQ(FreeBytes(data_.string()), 0u);

  const fs::path log = dir_.path() / "photorigd.log";
  const auto started = std::chrono::steady_clock::now();
  photorig::testing::DaemonProcess daemon(data_, options_.rig_path, log, {"--no-solve"});
  ApiClient client = ClientOf(daemon, log);
  const ServiceReply health = client.Get("/api/v1/health");
  const double health_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  RecordProperty("health_after_ms", static_cast<int>(health_s * 1000));
  EXPECT_LT(health_s, 15.0);  // a bound for a hang (retrying until there is room), not a speed figure
  EXPECT_EQ(health.http_status, 503) << health.body.dump();
  EXPECT_EQ(health.body["status"], "disk full") << health.body.dump();
  EXPECT_EQ(health.body["free_bytes"], 0);
  const ServiceReply runs = client.Get("/api/v1/runs");
  ASSERT_EQ(runs.http_status, 200) << runs.body.dump();
  ASSERT_EQ(runs.body["runs"].size(), 1u) << runs.body.dump();
  EXPECT_EQ(runs.body["runs"][0]["id"], id);
  EXPECT_EQ(runs.body["runs"][0]["state"], "done");
  EXPECT_EQ(client.Get("/api/v1/runs/" + id + "/files/manifest.json").http_status, 200);
  const ServiceReply refused = client.Post("/api/v1/runs", {{"name", "small.yaml"}, {"recipe", SmallRecipeYaml()}});
  EXPECT_EQ(refused.http_status, 507) << refused.body.dump();

  // Room again: the same daemon takes a run and completes it.
  fs::remove(data_ / "filler");
  ExpectARunCompletes(client, data_, log);
  EXPECT_EQ(daemon.Terminate(), 0) << ReadText(log);
}

// A data root named for the first time on a full disk: there is no queue to
// read, and none can be created yet.
TEST_F(FullDisk, PhotorigdStartsOnANewDataRootWithNoByteFreeAndCreatesItOnceThereIsRoom) {
  Fill();
  ASSERT_EQ(FreeBytes(data_.string()), 0u);
  const fs::path root = data_ / "new-root";
  const fs::path log = dir_.path() / "photorigd.log";
  const auto started = std::chrono::steady_clock::now();
  photorig::testing::DaemonProcess daemon(root, options_.rig_path, log, {"--no-solve"});
  ApiClient client = ClientOf(daemon, log);
  const ServiceReply health = client.Get("/api/v1/health");
  // Up and answering, not waiting for room: a bound for a hang (a start
  // that retried until the disk had room), far above a start on a busy machine.
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count(), 15.0);
  EXPECT_EQ(health.http_status, 503) << health.body.dump();
  EXPECT_EQ(health.body["status"], "disk full") << health.body.dump();
  const ServiceReply runs = client.Get("/api/v1/runs");
  ASSERT_EQ(runs.http_status, 200) << runs.body.dump();
  EXPECT_EQ(runs.body["runs"].size(), 0u) << runs.body.dump();
  EXPECT_EQ(client.Post("/api/v1/runs", {{"name", "small.yaml"}, {"recipe", SmallRecipeYaml()}}).http_status, 507);

  fs::remove(data_ / "filler");
  ExpectARunCompletes(client, root, log);
  EXPECT_TRUE(fs::exists(root / "queue.sqlite"));
  EXPECT_EQ(daemon.Terminate(), 0) << ReadText(log);
}

// A small dome for solves: 12 LEDs on two rings, a sphere on a 48 x 48 camera.
std::string SolveRigYaml() {
  std::string text = "rig: {name: solve-dome}\nlights:\n  driver: sim\n  id: solve-dome\n  leds:\n";
  for (int i = 0; i < 12; ++i) {
    const double azimuth = i * 2.0 * M_PI / 6.0 + (i >= 6 ? M_PI / 6.0 : 0.0);
    const double elevation = i < 6 ? 0.6 : 1.0;
    text += "    - {id: " + std::to_string(i) + ", direction: [" + std::to_string(std::cos(elevation) * std::cos(azimuth)) +
            ", " + std::to_string(std::cos(elevation) * std::sin(azimuth)) + ", " + std::to_string(std::sin(elevation)) +
            "]}\n";
  }
  text +=
      "camera: {driver: sim, id: solve-cam, width: 48, height: 48, pixel_pitch_mm: 0.5, bit_depth: 12, "
      "exposure_us: 1000}\n"
      "sim:\n  seed: 7\n  scene: {shape: sphere, radius_mm: 10}\n";
  return text;
}

// Photometric stereo, then svbrdf (normals again, albedo maps, EXR and a glTF asset).
std::string SolveRecipeYaml() {
  return "recipe: {name: solve-full, rig: rig.yaml}\n"
         "capture:\n  exposure_us: 1000\n  steps:\n    - dark: {count: 2}\n    - each_led: {leds: all}\n"
         "solve:\n"
         "  - photometric_stereo: {method: lambertian, shadow_threshold_sigma: 3}\n"
         "  - svbrdf: {photometric_stereo: {method: lambertian, shadow_threshold_sigma: 3}, max_materials: 1, "
         "held_out_lights: -1}\n";
}

std::uintmax_t BytesUnder(const fs::path& folder) {
  std::uintmax_t bytes = 0;
  for (const auto& entry : fs::recursive_directory_iterator(folder))
    if (entry.is_regular_file()) bytes += entry.file_size();
  return bytes;
}

// Every stored file of a run but its results, with its bytes.
std::map<std::string, std::string> CapturedFiles(const fs::path& run) {
  std::map<std::string, std::string> files;
  for (const auto& entry : fs::recursive_directory_iterator(run)) {
    const std::string relative = entry.path().lexically_relative(run).string();
    if (entry.is_regular_file() && relative.rfind("results", 0) != 0) files[relative] = ReadText(entry.path());
  }
  return files;
}

// What a solve that failed must not leave: partial folders, temp files.
void ExpectNoPartialResults(const fs::path& data) {
  for (const auto& entry : fs::recursive_directory_iterator(data)) {
    const std::string name = entry.path().filename().string();
    EXPECT_EQ(name.find(".partial-"), std::string::npos) << entry.path();
    EXPECT_NE(entry.path().extension(), ".tmp") << entry.path();
  }
}

TEST_F(FullDisk, ASolveThatRunsOutOfSpaceLeavesTheFramesAndSolvesOnceThereIsRoom) {
  const std::string recipe = dir_.Write("recipe.yaml", SolveRecipeYaml());
  dir_.Write("rig.yaml", SolveRigYaml());
  // The same run on a roomy disk: how much each stage writes.
  RunRequest request;
  request.recipe_path = recipe;
  request.output_directory = (dir_.path() / "reference").string();
  const RunOutcome reference = ExecuteRun(request);
  ASSERT_EQ(reference.solve_stages.size(), 2u);
  for (const SolveStageReport& stage : reference.solve_stages) ASSERT_TRUE(stage.usable) << stage.message;
  const std::map<std::string, std::uintmax_t> written = {
      {"photometric_stereo", BytesUnder(dir_.path() / "reference" / "results" / "ps")},
      {"svbrdf", BytesUnder(dir_.path() / "reference" / "results" / "svbrdf")}};
  ASSERT_GT(written.at("svbrdf"), 64u * 1024) << "the svbrdf results are too small to fill a disk part way";
  RecordProperty("ps_bytes", static_cast<int>(written.at("photometric_stereo")));
  RecordProperty("svbrdf_bytes", static_cast<int>(written.at("svbrdf")));

  // Each stage in turn runs out of space half way through its results.
  for (const auto& [stage_name, results] : {std::pair{"photometric_stereo", "ps"}, std::pair{"svbrdf", "svbrdf"}}) {
    const std::string full_stage = stage_name;
    SCOPED_TRACE(full_stage);
    const fs::path run = data_ / "runs" / full_stage;
    std::map<std::string, std::string> captured;
    request.output_directory = run.string();
    request.on_solve_started = [&](const std::string& stage) {
      if (stage != full_stage) return;
      captured = CapturedFiles(run);
      Fill(written.at(full_stage) / 2);
    };
    try {
      ExecuteRun(request);
      ADD_FAILURE() << "the solve wrote its results on a full disk";
    } catch (const std::runtime_error& e) {
      const std::string message = e.what();
      RecordProperty(full_stage + "_message", message);
      EXPECT_NE(message.find("cannot write the results to " + (run / "results" / results).string()), std::string::npos)
          << message;
      EXPECT_NE(message.find("No space left on device"), std::string::npos) << message;
      EXPECT_NE(message.find("free space on it, then solve again"), std::string::npos) << message;
      EXPECT_NE(message.find(std::string("`photorig solve ") + results + " --run " + run.string() + "`"),
                std::string::npos)
          << message;
    }
    ASSERT_FALSE(captured.empty());
    EXPECT_TRUE(CapturedFiles(run) == captured) << "the captured files changed";
    EXPECT_FALSE(fs::exists(run / "results" / results));
    ExpectNoPartialResults(data_);
    if (full_stage == "svbrdf") {  // the stage before it ended whole
      EXPECT_TRUE(fs::exists(run / "results" / "ps" / "report.json"));
    }
    fs::remove(data_ / "filler");
  }

  // `photorig solve` on the same disk: a full disk part way through is exit 1
  // naming the folder; with room again, the same command solves.
  const fs::path run = data_ / "runs" / "svbrdf";
  const std::map<std::string, std::string> captured = CapturedFiles(run);
  Fill(written.at("svbrdf") / 2);
  const photorig::testing::CommandOutcome full = Photorig("solve svbrdf --held-out=-1 --max-materials 1 --json --run " + run.string(), dir_);
  EXPECT_EQ(full.exit_code, 1) << full.err;
  const json document = json::parse(full.out, nullptr, false);
  ASSERT_TRUE(document.is_object()) << full.out;
  EXPECT_EQ(document.value("exit_code", -1), 1);
  EXPECT_NE(document.value("error", "").find("cannot write the results to " + (run / "results" / "svbrdf").string()),
            std::string::npos)
      << document.dump();
  EXPECT_NE(document.value("error", "").find("free space on it"), std::string::npos) << document.dump();
  EXPECT_FALSE(fs::exists(run / "results" / "svbrdf"));
  ExpectNoPartialResults(data_);
  fs::remove(data_ / "filler");

  for (const std::string solver : {"ps", "svbrdf --held-out=-1 --max-materials 1"}) {
    const photorig::testing::CommandOutcome solved = Photorig("solve " + solver + " --run " + run.string(), dir_);
    EXPECT_EQ(solved.exit_code, 0) << solver << ": " << solved.err;
    EXPECT_TRUE(fs::exists(run / "results" / solver.substr(0, solver.find(' ')) / "report.json")) << solver;
  }
  EXPECT_TRUE(fs::exists(run / "results" / "svbrdf" / "asset" / "asset.gltf"));
  EXPECT_TRUE(CapturedFiles(run) == captured) << "the captured files changed";
  ExpectNoPartialResults(data_);
}

}  // namespace
}  // namespace photorig::daemon
