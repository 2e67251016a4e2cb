// photorig-sim-modbus: the simulated Modbus LED controller of a rig (and,
// with --arms, the three gonioreflectometer arms) served as its own process,
// over Modbus TCP or over Modbus RTU on a pseudo-terminal.
//   photorig-sim-modbus --rig config/rigs/sim-dome-modbus.yaml --port 1502
//   photorig-sim-modbus --rig config/rigs/sim-dome-modbus.yaml --rtu
// Prints one line naming where it listens, then serves until SIGINT/SIGTERM.

#include "photorig/config/rig.h"
#include "photorig/config/sim.h"
#include "photorig/sim/modbus/internal/arm_peer.h"
#include "photorig/sim/modbus/led_peer.h"
#include "photorig/sim/modbus/server.h"

#include <CLI/CLI.hpp>

#include <csignal>
#include <cstdio>
#include <iostream>
#include <thread>

namespace {
volatile std::sig_atomic_t g_stop = 0;
}

int main(int argc, char** argv) {
  CLI::App app{"photorig-sim-modbus: simulated Modbus LED controller and arms"};
  std::string rig_path, host = "127.0.0.1";
  int port = 0;
  bool rtu = false, arms = false;
  std::vector<std::uint64_t> exception_at, disconnect_at, stall_moves, overshoot_moves;
  app.add_option("--rig", rig_path, "rig YAML with a sim: section (LED geometry and lights.options.map)")
      ->check(CLI::ExistingFile)
      ->required();
  app.add_option("--host", host, "IPv4 address to listen on");
  app.add_option("--port", port, "TCP port (0 = any free port)");
  app.add_flag("--rtu", rtu, "serve Modbus RTU on a pseudo-terminal instead of TCP");
  app.add_flag("--arms", arms, "also serve light_arm, camera_arm, sample_stage at 1000, 1100, 1200");
  app.add_option("--exception-at", exception_at, "reply 'server failure' to these requests (from 0)");
  app.add_option("--disconnect-at", disconnect_at, "drop the connection at these requests");
  app.add_option("--stall-move", stall_moves, "the arms stall half way through these moves");
  app.add_option("--overshoot-move", overshoot_moves, "the arms overshoot on these moves");
  CLI11_PARSE(app, argc, argv);

  namespace config = photorig::config;
  try {
    const config::RigConfig rig = config::LoadRigConfig(rig_path);
    if (!rig.sim) throw std::runtime_error(rig_path + ": the rig needs a sim: section");
    // The rig's register map when its lights are a Modbus controller; else a coil per LED.
    photorig::drivers::ModbusLightMap map;
    map.channels = static_cast<int>(rig.lights.leds.size());
    if (rig.lights.modbus) map = rig.lights.modbus->map;
    const auto world = std::make_shared<photorig::sim::World>(config::MakeWorldConfig(rig, rig.sim->scene));

    photorig::sim::ModbusServerOptions options;
    options.faults.exception_at = {exception_at.begin(), exception_at.end()};
    options.faults.disconnect_at = {disconnect_at.begin(), disconnect_at.end()};
    photorig::sim::SimModbusServer server(options);
    server.AddPeer(std::make_shared<photorig::sim::SimModbusLedController>(map, world));
    if (arms) {
      int base = 1000;
      for (const char* name : {"light_arm", "camera_arm", "sample_stage"}) {
        photorig::sim::SimArmOptions arm;
        arm.name = name;
        arm.base_address = base;
        base += 100;
        arm.stall_moves = {stall_moves.begin(), stall_moves.end()};
        arm.overshoot_moves = {overshoot_moves.begin(), overshoot_moves.end()};
        server.AddPeer(std::make_shared<photorig::sim::SimArm>(arm));
      }
    }
    const photorig::Status started = rtu ? server.StartRtu() : server.StartTcp(host, port);
    if (!started.ok()) throw std::runtime_error(started.ToString());
    if (rtu) std::cout << "rtu " << server.rtu_path() << std::endl;
    else std::cout << "tcp " << host << ":" << server.port() << std::endl;

    std::signal(SIGINT, [](int) { g_stop = 1; });
    std::signal(SIGTERM, [](int) { g_stop = 1; });
    while (!g_stop) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    server.Stop();
    std::cerr << "served " << server.requests() << " requests" << std::endl;
  } catch (const std::exception& e) {
    std::cerr << "photorig-sim-modbus: " << e.what() << std::endl;
    return 1;
  }
  return 0;
}
