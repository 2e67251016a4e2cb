// One photorigd per port: a second daemon started on a port the first holds
// exits 2 naming the port and the process that holds it, and every new
// connection still reaches the first (SO_REUSEPORT would have let both
// listen and shared the connections between them).

#include "photorig/daemon/service/internal/api_client.h"
#include "photorig/daemon/service/api_server.h"
#include "daemon_process.h"

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <string>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
using photorig::testing::DaemonProcess;
using photorig::testing::ReadText;
using photorig::testing::TempDir;

TEST(OnePort, ASecondDaemonOnAHeldPortExits2AndTheFirstKeepsEveryConnection) {
  TempDir dir;
  const std::string rig = dir.Write("rig.yaml", photorig::testing::SmallRigYaml());
  const fs::path first_log = dir.path() / "first.log", second_log = dir.path() / "second.log";
  DaemonProcess first(dir.path() / "data-first", rig, first_log, {"--no-solve"});
  const int port = first.WaitReady(first_log, 0);
  ASSERT_GT(port, 0) << ReadText(first_log);
  const auto client = [port] {
    ApiClientOptions options;
    options.url = "http://127.0.0.1:" + std::to_string(port);
    options.timeout_s = 10;
    return ApiClient(options);
  };
  const auto submitted = client().Post("/api/v1/runs", {{"recipe", photorig::testing::SmallRecipeYaml()}});
  ASSERT_EQ(submitted.http_status, 201) << submitted.body.dump();
  const std::string id = submitted.body["id"];

  // Another rig's daemon with its own data root, on the same port.
  const auto started = std::chrono::steady_clock::now();
  DaemonProcess second(dir.path() / "data-second", rig, second_log, {"--no-solve"}, port);
  const int code = second.WaitExit(std::chrono::seconds(2));
  EXPECT_EQ(code, 2) << ReadText(second_log);
  EXPECT_LT(std::chrono::steady_clock::now() - started, std::chrono::seconds(2));
  const std::string said = ReadText(second_log);
  EXPECT_NE(said.find(":" + std::to_string(port)), std::string::npos) << said;
  EXPECT_NE(said.find("held by process " + std::to_string(first.pid()) + " (photorigd)"), std::string::npos) << said;
  EXPECT_FALSE(fs::exists(dir.path() / "data-second" / "runs" / id));

  // Each request on a new connection: all reach the first daemon, whose run they list.
  for (int i = 0; i < 20; ++i) {
    const auto runs = client().Get("/api/v1/runs");
    ASSERT_EQ(runs.http_status, 200) << i;
    ASSERT_EQ(runs.body["runs"].size(), 1u) << i << ": " << runs.body.dump();
    EXPECT_EQ(runs.body["runs"][0]["id"], id);
  }
}

TEST(OnePort, PortHolderNamesTheListeningProcess) {
  TempDir dir;
  const fs::path log = dir.path() / "photorigd.log";
  DaemonProcess daemon(dir.path() / "data", dir.Write("rig.yaml", photorig::testing::SmallRigYaml()), log, {});
  const int port = daemon.WaitReady(log, 0);
  ASSERT_GT(port, 0) << ReadText(log);
  EXPECT_EQ(PortHolder(port), "process " + std::to_string(daemon.pid()) + " (photorigd)");
}

}  // namespace
}  // namespace photorig::daemon
