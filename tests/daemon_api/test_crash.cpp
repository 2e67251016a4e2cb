// kill -9 of the real photorigd at seeded random points of a capture, again
// and again, while the simulated devices drop, damage and refuse at seeded
// points of every process's life. After each kill the journal never vouches
// for a frame that is missing or damaged; after each restart the daemon
// resumes the run; at the end every step's frame is on disk exactly once and
// intact. The suite runs 12 kills over 64 steps; scripts/soak.sh runs the
// same test at any scale (PHOTORIG_SOAK_KILLS, PHOTORIG_SOAK_DARKS,
// PHOTORIG_SOAK_SEED).

#include "photorig/daemon/service/internal/api_client.h"
#include "photorig/daemon/capture/run_store.h"
#include "daemon_process.h"

#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <regex>
#include <thread>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using photorig::testing::DaemonProcess;
using photorig::testing::ReadText;
using photorig::testing::TempDir;

int FromEnvironment(const char* name, int fallback) {
  const char* text = std::getenv(name);
  return text ? std::max(1, std::atoi(text)) : fallback;
}

const int kKills = FromEnvironment("PHOTORIG_SOAK_KILLS", 12);
const int kDarks = FromEnvironment("PHOTORIG_SOAK_DARKS", 60);
const int kSteps = kDarks + 4;  // the darks, then 4 LEDs
const unsigned kSeed = static_cast<unsigned>(FromEnvironment("PHOTORIG_SOAK_SEED", 20261122));

// Transient faults at seeded frame and command counts; the counts start again
// with every process, so each start meets them anew (retried, never fatal:
// five or six per start against the 20 retries a run may spend).
std::string SeededFaults(std::mt19937& rng) {
  std::uniform_int_distribution<int> at(0, std::max(8, kSteps / 4));
  const auto list = [&](int n) {
    std::string text = "[";
    for (int i = 0; i < n; ++i) text += (i ? ", " : "") + std::to_string(at(rng));
    return text + "]";
  };
  return "{camera: {drop_frames: " + list(2) + ", corrupt_frames: " + list(1) + ", short_frames: " + list(1) +
         "}, lights: {fail_commands: " + list(1) + "}}";
}

// The daemon of this test: capture only, retries without delay.
std::unique_ptr<DaemonProcess> StartDaemon(const fs::path& data, const std::string& rig, const fs::path& log) {
  return std::make_unique<DaemonProcess>(data, rig, log, std::vector<std::string>{"--no-solve", "--backoff-ms", "1"});
}

ApiClient Client(int port) {
  ApiClientOptions options;
  options.url = "http://127.0.0.1:" + std::to_string(port);
  options.timeout_s = 10;
  return ApiClient(options);
}

// The frames a run's journal holds (lines with a checksum).
int JournalFrames(const fs::path& run) {
  std::ifstream journal(run / "journal.jsonl");
  int lines = 0;
  for (std::string line; std::getline(journal, line);) lines += line.find("\"crc32\"") != std::string::npos;
  return lines;
}

TEST(Crash, KillNineAtRandomPointsLosesAndDuplicatesNoFrame) {
  TempDir dir;
  const fs::path data = dir.path() / "data", log = dir.path() / "photorigd.log";
  std::mt19937 rng(kSeed);
  const std::string rig = dir.Write("rig.yaml", photorig::testing::SmallRigYaml(SeededFaults(rng)));
  std::uniform_int_distribution<int> delay_ms(5, 120);

  int starts = 0;
  auto daemon = StartDaemon(data, rig, log);
  int port = daemon->WaitReady(log, starts++);
  ASSERT_GT(port, 0) << ReadText(log);
  const auto submitted =
      Client(port).Post("/api/v1/runs", {{"recipe", photorig::testing::SmallRecipeYaml("", kDarks)}});
  ASSERT_EQ(submitted.http_status, 201) << submitted.body.dump();
  const std::string id = submitted.body["id"];
  const fs::path run = data / "runs" / id;

  // Kill when the journal reaches a random frame count ahead of where it is, so
  // every kill lands mid-capture however fast this machine writes.
  int kills_during_capture = 0;
  for (int kill = 0; kill < kKills; ++kill) {
    const int now = JournalFrames(run);
    const int target = std::min(kSteps - 1, now + 1 + delay_ms(rng) % std::max(1, (kSteps - now) / (kKills - kill)));
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (JournalFrames(run) < target && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    daemon->Kill();
    // What the journal vouches for is on disk and intact (checked on a copy,
    // since reopening repairs).
    if (fs::exists(run / "journal.jsonl")) {
      const fs::path copy = dir.path() / ("copy" + std::to_string(kill));
      fs::copy(run, copy, fs::copy_options::recursive);
      RecoveryReport recovery;
      RunWriter::Reopen(copy.string(), &recovery);
      EXPECT_EQ(recovery.frames_discarded, 0) << "kill " << kill;
      kills_during_capture += recovery.frames_kept < kSteps;
      fs::remove_all(copy);
    }
    daemon = StartDaemon(data, rig, log);
    port = daemon->WaitReady(log, starts++);
    ASSERT_GT(port, 0) << ReadText(log);
  }
  EXPECT_GE(kills_during_capture, kKills / 2);

  // Let the last start finish the run, then stop it gracefully.
  json state;
  for (int i = 0; i < 300 + kSteps; ++i) {
    state = Client(port).Get("/api/v1/runs/" + id).body;
    if (state.value("state", "") == "done") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_EQ(daemon->Terminate(), 0);
  ASSERT_EQ(state["state"], "done") << state.dump() << ReadText(log);
  const auto problems = VerifyRun(run.string());
  EXPECT_TRUE(problems.empty()) << problems.front();
  const RunManifest manifest = LoadRunManifest(run.string());
  EXPECT_EQ(manifest.frames.size(), static_cast<std::size_t>(kSteps));
  ASSERT_TRUE(manifest.stop.has_value());
  EXPECT_EQ(manifest.stop->status, CaptureStatus::kComplete);
  EXPECT_EQ(manifest.stop->frames, kSteps);
  // Every device fault suspended the run for a retry, across all starts.
  const std::string text = ReadText(log);
  int suspensions = 0;
  for (std::size_t at = text.find("state=suspended"); at != std::string::npos; at = text.find("state=suspended", at + 1))
    ++suspensions;
  EXPECT_GT(suspensions, 0) << "the seeded device faults never fired";
  std::printf("soak: %d kills (%d mid-capture), %d device faults retried, %d steps, every frame once and intact\n",
              kKills, kills_during_capture, suspensions, kSteps);
}

// A run resumed at a restart shows the frames its journal kept as soon as the
// daemon answers, not 0 until its next frame.
TEST(Crash, AResumedRunShowsTheFramesItKeptRightAfterARestart) {
  TempDir dir;
  const fs::path data = dir.path() / "data", log = dir.path() / "photorigd.log";
  const std::string rig = dir.Write("rig.yaml", photorig::testing::SmallRigYaml());
  auto daemon = StartDaemon(data, rig, log);
  int port = daemon->WaitReady(log, 0);
  ASSERT_GT(port, 0) << ReadText(log);
  const auto submitted = Client(port).Post("/api/v1/runs", {{"recipe", photorig::testing::SmallRecipeYaml("", 1000)}});
  ASSERT_EQ(submitted.http_status, 201) << submitted.body.dump();
  const std::string id = submitted.body["id"];
  const fs::path run = data / "runs" / id;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);  // a hang guard
  while (JournalFrames(run) < 20 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  daemon->Kill();
  const int kept = JournalFrames(run);
  ASSERT_GE(kept, 20);

  daemon = StartDaemon(data, rig, log);
  port = daemon->WaitReady(log, 1);
  ASSERT_GT(port, 0) << ReadText(log);
  const json shown = Client(port).Get("/api/v1/runs/" + id).body;
  RecordProperty("frames_kept", kept);
  RecordProperty("frames_shown", shown.value("frames", -1));
  EXPECT_GE(shown.value("frames", 0), kept) << shown.dump();
  EXPECT_EQ(daemon->Terminate(), 0);
}

}  // namespace
}  // namespace photorig::daemon
