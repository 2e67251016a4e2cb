// 64 concurrent dry-runs of the largest recipe photorigd accepts (100 000
// frames on a 96-LED dome) against the real daemon: the plans share one
// memory budget, so its resident size peaks under 1 GB, falls back under
// 300 MB once they are answered, and every request is answered in the end
// (503 with Retry-After while the budget is spent, then the plan).

#include "daemon_process.h"

#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include <signal.h>

#include <atomic>
#include <chrono>
#include <fstream>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace photorig::daemon {
namespace {

using nlohmann::json;
using photorig::testing::DaemonProcess;
using photorig::testing::ReadText;
using photorig::testing::SmallRigYaml;
using photorig::testing::TempDir;

// A /proc/<pid>/status figure in kB (VmRSS, VmHWM); -1 when the process is gone.
long StatusKb(pid_t pid, const std::string& key) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind(key + ":", 0) == 0) return std::stol(line.substr(key.size() + 1));
  return -1;
}

TEST(PlanMemory, SixtyFourConcurrentLargestDryRunsStayUnderAGigabyte) {
  TempDir dir;
  const std::string rig = dir.Write("rig.yaml", SmallRigYaml("", 96));
  // 4 000 darks, then each of the 96 LEDs 1 000 times: 100 000 frames, the limit.
  const std::string recipe =
      "recipe: {name: largest}\ncapture:\n  exposure_us: 1000\n  steps:\n    - dark: {count: 1000, repeat: 4}\n"
      "    - each_led: {leds: all, repeat: 1000}\n";
  const auto log = dir.path() / "photorigd.log";
  DaemonProcess daemon(dir.path() / "data", rig, log, {"--no-solve"});
  const int port = daemon.WaitReady(log, 0);
  ASSERT_GT(port, 0) << ReadText(log);
  const long rss_before_kb = StatusKb(daemon.pid(), "VmRSS");

  constexpr int kClients = 64;
  std::atomic<bool> done{false};
  long sampled_peak_kb = 0;
  std::thread sampler([&] {
    while (!done) {
      sampled_peak_kb = std::max(sampled_peak_kb, StatusKb(daemon.pid(), "VmRSS"));
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  });
  std::mutex mutex;
  std::vector<std::string> failures;
  std::atomic<int> answered{0}, busy{0};
  const std::string body = json{{"name", "largest.yaml"}, {"recipe", recipe}}.dump();
  std::vector<std::thread> clients;
  for (int c = 0; c < kClients; ++c)
    clients.emplace_back([&] {
      httplib::Client client("127.0.0.1", port);
      client.set_read_timeout(120, 0);
      const auto give_up = std::chrono::steady_clock::now() + std::chrono::minutes(5);  // a hang guard
      while (std::chrono::steady_clock::now() < give_up) {
        const auto reply = client.Post("/api/v1/dry-run", body, "application/json");
        if (reply && reply->status == 503 && reply->has_header("Retry-After")) {
          ++busy;
          std::this_thread::sleep_for(std::chrono::seconds(std::stoi(reply->get_header_value("Retry-After"))));
          continue;
        }
        const json answer = reply ? json::parse(reply->body, nullptr, false) : json();
        if (reply && reply->status == 200 && answer.is_object() && answer.value("frames", 0) == 100000 &&
            answer["steps"].size() == 10000u) {
          ++answered;
        } else {
          std::lock_guard lock(mutex);
          failures.push_back(reply ? std::to_string(reply->status) + " " + reply->body.substr(0, 300)
                                   : "no answer: " + httplib::to_string(reply.error()));
        }
        return;
      }
      std::lock_guard lock(mutex);
      failures.push_back("still refused after 5 minutes");
    });
  for (std::thread& client : clients) client.join();
  done = true;
  sampler.join();

  ASSERT_EQ(::kill(daemon.pid(), 0), 0) << "photorigd died: " << ReadText(log);
  const long peak_kb = StatusKb(daemon.pid(), "VmHWM");
  // The last answers' memory is returned as their reservations end; a moment for the last one.
  long after_kb = StatusKb(daemon.pid(), "VmRSS");
  for (int i = 0; i < 50 && after_kb > 300 * 1024; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    after_kb = StatusKb(daemon.pid(), "VmRSS");
  }
  RecordProperty("rss_before_kb", static_cast<int>(rss_before_kb));
  RecordProperty("peak_kb", static_cast<int>(peak_kb));
  RecordProperty("sampled_peak_kb", static_cast<int>(sampled_peak_kb));
  RecordProperty("after_kb", static_cast<int>(after_kb));
  RecordProperty("busy_answers", busy.load());
  std::printf("photorigd RSS: %ld kB before, peak %ld kB (sampled %ld kB), %ld kB after; %d answers 503 on the way\n",
              rss_before_kb, peak_kb, sampled_peak_kb, after_kb, busy.load());

  EXPECT_TRUE(failures.empty()) << failures.size() << " failed, the first: " << failures.front();
  EXPECT_EQ(answered, kClients);
  EXPECT_LE(peak_kb, 1024 * 1024) << "peak resident size above 1 GB";
  EXPECT_LE(after_kb, 300 * 1024) << "resident size not back under 300 MB";
  httplib::Client client("127.0.0.1", port);
  const auto health = client.Get("/api/v1/health");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200) << health->body;
  EXPECT_EQ(daemon.Terminate(), 0) << ReadText(log);
}

}  // namespace
}  // namespace photorig::daemon
