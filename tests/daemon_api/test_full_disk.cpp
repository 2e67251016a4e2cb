// A data root on a full filesystem (a small tmpfs, mounted by the test as
// root): the run fails cleanly, no temp file holds space, the daemon keeps
// running, starts while the disk is full and says so on /health, and the run
// gets its stop record and manifest once there is room again.

#include "photorig/daemon/run_store.h"
#include "photorig/daemon/service.h"
#include "test_support.h"

#include <gtest/gtest.h>

#include <sys/mount.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
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
  // Writes until the filesystem refuses.
  void Fill() {
    std::ofstream filler(data_ / "filler", std::ios::binary);
    const std::string block(64 * 1024, 'x');
    while (filler.write(block.data(), block.size()) && filler.flush()) {
    }
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

}  // namespace
}  // namespace photorig::daemon
