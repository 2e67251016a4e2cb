// The simulated dome as its own process (photorig-sim-modbus), and a whole
// photometric-stereo run whose lights go over real Modbus TCP.

#include "photorig/config/rig.h"
#include "photorig/drivers/light_safety.h"
#include "photorig/drivers/modbus/modbus_lights.h"
#include "photorig/drivers/motion/modbus_drive.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

namespace photorig {
namespace {

namespace fs = std::filesystem;

std::string SourceDir() {
  const char* dir = std::getenv("PHOTORIG_SOURCE_DIR");
  return dir ? dir : ".";
}

// Starts the server process and reads the line naming where it listens.
struct ServerProcess {
  pid_t pid = -1;
  FILE* out = nullptr;
  std::string where;

  explicit ServerProcess(const std::vector<std::string>& args) {
    int pipe_fds[2];
    EXPECT_EQ(::pipe(pipe_fds), 0);
    pid = ::fork();
    if (pid == 0) {
      ::dup2(pipe_fds[1], STDOUT_FILENO);
      ::close(pipe_fds[0]);
      std::vector<char*> argv;
      const std::string binary = std::string(PHOTORIG_BIN_DIR) + "/photorig-sim-modbus";
      argv.push_back(const_cast<char*>(binary.c_str()));
      for (const auto& arg : args) argv.push_back(const_cast<char*>(arg.c_str()));
      argv.push_back(nullptr);
      ::execv(binary.c_str(), argv.data());
      std::_Exit(127);
    }
    ::close(pipe_fds[1]);
    out = ::fdopen(pipe_fds[0], "r");
    char line[256] = {};
    if (std::fgets(line, sizeof(line), out)) where = line;
    while (!where.empty() && where.back() == '\n') where.pop_back();
  }
  int Terminate() {
    ::kill(pid, SIGTERM);
    int status = 0;
    ::waitpid(pid, &status, 0);
    std::fclose(out);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
};

TEST(SimModbusProcess, ServesTheDomeAndArmsOverTcpAndStopsOnSigterm) {
  const std::string rig = SourceDir() + "/config/rigs/sim-dome-modbus.yaml";
  ServerProcess server({"--rig", rig, "--arms"});
  ASSERT_EQ(server.where.rfind("tcp 127.0.0.1:", 0), 0u) << server.where;
  const int port = std::stoi(server.where.substr(std::string("tcp 127.0.0.1:").size()));

  // The map the client uses is the rig's own.
  const config::RigConfig config = config::LoadRigConfig(rig);
  ASSERT_TRUE(config.lights.modbus.has_value());
  const drivers::ModbusLightMap& map = config.lights.modbus->map;
  drivers::ModbusLinkOptions link;
  link.port = port;
  drivers::ModbusLightController lights("dome", link, map);
  ASSERT_TRUE(lights.Open().ok());
  drivers::LightPattern pattern = drivers::LightPattern::AllOff(48);
  pattern.levels[47] = 0.3;
  pattern.levels[0] = 1.0;
  ASSERT_TRUE(lights.SetPattern(pattern).ok());
  auto back = lights.ReadBack();
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back->levels, pattern.levels);
  ASSERT_TRUE(lights.Close().ok());

  drivers::ModbusDriveAxis arm("camera_arm", link, 1100, {-90, 90}, {});
  ASSERT_TRUE(arm.Open().ok());
  ASSERT_TRUE(arm.Home().ok());
  ASSERT_TRUE(arm.MoveTo(12.5, {300, 3000}).ok());
  EXPECT_NEAR(arm.Poll()->position_deg, 12.5, 1e-3);
  ASSERT_TRUE(arm.Close().ok());

  EXPECT_EQ(server.Terminate(), 0);
}

// The process that lit an LED dies outright (SIGKILL: no handler, no
// atexit, no SafetyNet): the controller's own communication-loss watchdog,
// armed by the driver from the rig's map, switches the LED off.
TEST(SimModbusProcess, AnLedLitByAKilledProcessGoesDarkWithinTheControllersTimeout) {
  const std::string rig = SourceDir() + "/config/rigs/sim-dome-modbus.yaml";
  const config::RigConfig config = config::LoadRigConfig(rig);
  const drivers::ModbusLightMap& map = config.lights.modbus->map;
  ASSERT_GE(map.watchdog_address, 0) << "the rig arms the controller's watchdog";
  ServerProcess server({"--rig", rig});
  const int port = std::stoi(server.where.substr(std::string("tcp 127.0.0.1:").size()));
  drivers::ModbusLinkOptions link;
  link.port = port;

  int lit[2];
  ASSERT_EQ(::pipe(lit), 0);
  const pid_t child = ::fork();
  if (child == 0) {
    // As the daemon drives it: the driver behind the safety layer, whose
    // monitor keeps the dead-man alive for as long as this process lives
    // (the rig's 2 s on-time limit lifted, so the hold outlasts the timeout).
    drivers::LightSafetyOptions safety = config.lights.safety;
    safety.defaults.max_on_ms = 0;
    drivers::SafeLightController lights(std::make_unique<drivers::ModbusLightController>("dome", link, map), safety);
    const bool ok = lights.Open().ok() && lights.SetPattern(drivers::LightPattern::Single(48, 5, 1.0)).ok();
    const char byte = ok ? 1 : 0;
    (void)!::write(lit[1], &byte, 1);
    for (;;) ::pause();
  }
  char byte = 0;
  ASSERT_EQ(::read(lit[0], &byte, 1), 1);
  ASSERT_EQ(byte, 1) << "the child could not light LED 5";
  // Held lit while the process lives (longer than the 2 s timeout).
  std::this_thread::sleep_for(std::chrono::milliseconds(2500));
  drivers::ModbusLink probe("probe", link);
  ASSERT_TRUE(probe.Connect().ok());
  EXPECT_EQ(probe.ReadCoils(map.on_off_address + 5, 1).value()[0], 1) << "kept alive while the process lives";
  probe.Disconnect();

  ::kill(child, SIGKILL);
  ::waitpid(child, nullptr, 0);
  // No request from anyone now (a probe would itself keep the controller alive).
  std::this_thread::sleep_for(std::chrono::milliseconds(map.watchdog_timeout_ms + 500));
  ASSERT_TRUE(probe.Connect().ok());
  EXPECT_EQ(probe.ReadCoils(map.on_off_address + 5, 1).value()[0], 0) << "still lit after the controller's timeout";
  EXPECT_EQ(probe.ReadRegisters(map.intensity_address + 5, 1).value()[0], 0);
  probe.Disconnect();
  EXPECT_EQ(server.Terminate(), 0);
}

// An LED left lit by a process that is gone (here: set by hand on a
// controller without a watchdog) goes dark when photorigd starts, even with
// --no-resume, before any run.
// `rig_path` as a lab's rig would be: the controller at the server's address,
// not served in-process. Written into `dir` as rig.yaml.
fs::path ExternalControllerRig(const std::string& rig_path, int port, const fs::path& dir) {
  fs::create_directories(dir);
  std::ifstream in(rig_path);
  std::string rig((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  rig.replace(rig.find("    host: sim"), 13, "    host: 127.0.0.1");
  rig.replace(rig.find("    port: 0 "), 12, "    port: " + std::to_string(port) + " ");
  std::ofstream(dir / "rig.yaml") << rig;
  return dir / "rig.yaml";
}

// The simulated controller as its own process, the port it serves and its
// register map, and a probe connection that lights an LED the way a process
// that died mid-capture leaves it.
struct ControllerProcess {
  std::string rig_path = SourceDir() + "/config/rigs/sim-dome-modbus.yaml";
  ServerProcess server{{"--rig", rig_path}};
  int port = std::stoi(server.where.substr(std::string("tcp 127.0.0.1:").size()));
  drivers::ModbusLightMap map = config::LoadRigConfig(rig_path).lights.modbus->map;
  drivers::ModbusLink probe{"probe", LinkTo(port)};

  static drivers::ModbusLinkOptions LinkTo(int port) {
    drivers::ModbusLinkOptions link;
    link.port = port;
    return link;
  }

  bool LightFromOutside(int led) {
    return probe.Connect().ok() && probe.WriteRegisters(map.intensity_address + led, {1000}).ok() &&
           probe.WriteCoils(map.on_off_address + led, {1}).ok();
  }
};

// What systemd's ExecStopPost runs after photorigd ended however it ended:
// an LED a dead process left lit goes dark.
TEST(SimModbusProcess, LightsOffDarkensWhatAProcessLeftLit) {
  ControllerProcess controller;
  ASSERT_TRUE(controller.LightFromOutside(3));
  const fs::path dir = fs::temp_directory_path() / ("photorig-lights-off-" + std::to_string(::getpid()));
  const fs::path rig = ExternalControllerRig(controller.rig_path, controller.port, dir);
  const std::string command = std::string(PHOTORIG_BIN_DIR) + "/photorig lights off --json --rig " + rig.string() +
                              " > " + (dir / "out.json").string() + " 2> " + (dir / "err.txt").string();
  const int status = std::system(command.c_str());
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
  std::ifstream out(dir / "out.json");
  const nlohmann::json document = nlohmann::json::parse(out, nullptr, false);
  EXPECT_TRUE(document.is_object() && document.value("touched", false)) << document.dump();
  EXPECT_EQ(controller.probe.ReadCoils(controller.map.on_off_address + 3, 1).value()[0], 0);
  controller.probe.Disconnect();
  fs::remove_all(dir);
  EXPECT_EQ(controller.server.Terminate(), 0);
}

TEST(SimModbusProcess, PhotorigdStartsByDarkeningTheLights) {
  ControllerProcess controller;
  ASSERT_TRUE(controller.LightFromOutside(7));

  const fs::path dir = fs::temp_directory_path() / ("photorig-darken-" + std::to_string(::getpid()));
  ExternalControllerRig(controller.rig_path, controller.port, dir);
  const pid_t daemon = ::fork();
  if (daemon == 0) {
    const std::string binary = std::string(PHOTORIG_BIN_DIR) + "/photorigd";
    const std::string rig_file = (dir / "rig.yaml").string(), root = (dir / "data").string();
    ::execl(binary.c_str(), binary.c_str(), "--rig", rig_file.c_str(), "--data-root", root.c_str(), "--port", "0",
            "--no-resume", static_cast<char*>(nullptr));
    std::_Exit(127);
  }
  bool dark = false;
  for (int i = 0; i < 100 && !dark; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    dark = controller.probe.ReadCoils(controller.map.on_off_address + 7, 1).value()[0] == 0;
  }
  EXPECT_TRUE(dark) << "LED 7 still lit 10 s after photorigd started";
  ::kill(daemon, SIGTERM);
  ::waitpid(daemon, nullptr, 0);
  controller.probe.Disconnect();
  fs::remove_all(dir);
  EXPECT_EQ(controller.server.Terminate(), 0);
}

TEST(SimModbusProcess, ServesRtuOnAPseudoTerminal) {
  ServerProcess server({"--rig", SourceDir() + "/config/rigs/sim-dome-modbus.yaml", "--rtu"});
  ASSERT_EQ(server.where.rfind("rtu /dev/", 0), 0u) << server.where;
  drivers::ModbusLinkOptions link;
  link.transport = drivers::ModbusLinkOptions::Transport::kRtu;
  link.serial_device = server.where.substr(4);
  link.baud = 115200;
  drivers::ModbusLightMap map;
  map.channels = 48;
  map.intensity = true;
  drivers::ModbusLightController lights("dome", link, map);
  ASSERT_TRUE(lights.Open().ok());
  EXPECT_TRUE(lights.SetPattern(drivers::LightPattern::Single(48, 9, 0.5)).ok());
  EXPECT_EQ(lights.ReadBack()->levels[9], 0.5);
  EXPECT_TRUE(lights.Close().ok());
  EXPECT_EQ(server.Terminate(), 0);
}

TEST(EndToEnd, PhotometricStereoRunOverModbusTcp) {
  const fs::path dir = fs::temp_directory_path() / ("photorig-modbus-e2e-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const fs::path run = dir / "run";
  fs::create_directories(dir);
  const std::string command = std::string(PHOTORIG_BIN_DIR) + "/photorig run " + SourceDir() +
                              "/config/recipes/ps-sphere.yaml --rig " + SourceDir() +
                              "/config/rigs/sim-dome-modbus.yaml --out " + run.string() + " > " +
                              (dir / "log").string() + " 2>&1";
  const int status = std::system(command.c_str());
  std::ifstream log_file(dir / "log");
  const std::string log((std::istreambuf_iterator<char>(log_file)), std::istreambuf_iterator<char>());
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << log;

  std::ifstream manifest_file(run / "manifest.json");
  const auto manifest = nlohmann::json::parse(manifest_file);
  EXPECT_EQ(manifest["status"], "complete");
  EXPECT_EQ(manifest["rig"]["name"], "sim-dome-modbus");
  ASSERT_EQ(manifest["frames"].size(), 49u);
  EXPECT_EQ(manifest["lights"][0]["rgb_intensity"], nlohmann::json({1.00, 0.97, 0.91}));
  EXPECT_EQ(manifest["lights"][1]["rgb_intensity"], nlohmann::json({1.0, 1.0, 1.0}));

  std::ifstream report_file(run / "results/ps/report.json");
  const auto report = nlohmann::json::parse(report_file);
  EXPECT_EQ(report["termination"], "success");
  EXPECT_LT(report["ground_truth"]["mean_angular_error_deg"].get<double>(), 1.0);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace photorig
