// kill -9 of the real photorigd at seeded random points of a capture, again
// and again. After each kill the journal never vouches for a frame that is
// missing or damaged; after each restart the daemon resumes the run; at the
// end every step's frame is on disk exactly once and intact.

#include "photorig/daemon/api_client.h"
#include "photorig/daemon/run_store.h"
#include "daemon_process.h"

#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
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

constexpr int kKills = 12;
constexpr int kSteps = 64;  // 60 darks + 4 LEDs

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

TEST(Crash, KillNineAtRandomPointsLosesAndDuplicatesNoFrame) {
  TempDir dir;
  const fs::path data = dir.path() / "data", log = dir.path() / "photorigd.log";
  const std::string rig = dir.Write("rig.yaml", photorig::testing::SmallRigYaml());
  std::mt19937 rng(20261122);
  std::uniform_int_distribution<int> delay_ms(5, 120);

  int starts = 0;
  auto daemon = StartDaemon(data, rig, log);
  int port = daemon->WaitReady(log, starts++);
  ASSERT_GT(port, 0) << ReadText(log);
  const auto submitted = Client(port).Post("/api/v1/runs", {{"recipe", photorig::testing::SmallRecipeYaml("", 60)}});
  ASSERT_EQ(submitted.http_status, 201) << submitted.body.dump();
  const std::string id = submitted.body["id"];
  const fs::path run = data / "runs" / id;

  // Kill when the journal reaches a random frame count ahead of where it is, so
  // every kill lands mid-capture however fast this machine writes.
  auto journal_frames = [&run] {
    std::ifstream journal(run / "journal.jsonl");
    int lines = 0;
    for (std::string line; std::getline(journal, line);) lines += line.find("\"crc32\"") != std::string::npos;
    return lines;
  };
  int kills_during_capture = 0;
  for (int kill = 0; kill < kKills; ++kill) {
    const int now = journal_frames();
    const int target = std::min(kSteps - 1, now + 1 + delay_ms(rng) % std::max(1, (kSteps - now) / (kKills - kill)));
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (journal_frames() < target && std::chrono::steady_clock::now() < deadline)
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
  for (int i = 0; i < 300; ++i) {
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
}

}  // namespace
}  // namespace photorig::daemon
