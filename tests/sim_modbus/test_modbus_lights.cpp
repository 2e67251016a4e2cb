// The Modbus LED driver against the simulated controller, over real Modbus
// TCP on loopback and Modbus RTU on a pseudo-terminal pair.

#include "photorig/drivers/light_safety.h"
#include "photorig/drivers/modbus/modbus_lights.h"
#include "photorig/sim/devices.h"
#include "photorig/sim/modbus/led_peer.h"
#include "photorig/sim/modbus/server.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include <ostream>
#include <string>
#include <thread>

namespace photorig {
namespace {

using drivers::LightPattern;
using drivers::ModbusLightController;
using drivers::ModbusLightMap;
using drivers::ModbusLinkOptions;

std::shared_ptr<sim::World> DomeWorld(int leds, sim::LightFaults faults = {}) {
  sim::WorldConfig config;
  config.scene.shape = sim::Scene::Shape::kSphere;
  config.scene.sphere_radius_mm = 2.0;
  config.camera = {32, 24, 0.2};
  for (int i = 0; i < leds; ++i) {
    const double azimuth = 2 * CV_PI * i / leds;
    config.lights.push_back({Eigen::Vector3d(0.6 * std::cos(azimuth), 0.6 * std::sin(azimuth), 0.8), 1.0});
  }
  config.light_faults = faults;
  return std::make_shared<sim::World>(config);
}

ModbusLightMap Map(int channels, ModbusLightMap::Switch on_off, bool intensity) {
  ModbusLightMap map;
  map.channels = channels;
  map.on_off = on_off;
  map.on_off_address = on_off == ModbusLightMap::Switch::kBitmask ? 500 : 10;
  map.intensity = intensity;
  map.intensity_address = 100;
  map.full_scale = 1000;
  return map;
}

struct Bench {
  std::shared_ptr<sim::World> world;
  std::shared_ptr<sim::SimModbusLedController> peer;
  std::unique_ptr<sim::SimModbusServer> server;
  ModbusLinkOptions link;

  Bench(const ModbusLightMap& map, bool rtu = false, sim::ModbusServerFaults faults = {}, sim::LightFaults light = {})
      : world(DomeWorld(map.channels, light)) {
    sim::ModbusServerOptions options;
    options.faults = faults;
    server = std::make_unique<sim::SimModbusServer>(options);
    peer = std::make_shared<sim::SimModbusLedController>(map, world);
    server->AddPeer(peer);
    EXPECT_TRUE((rtu ? server->StartRtu() : server->StartTcp()).ok());
    link.transport = rtu ? ModbusLinkOptions::Transport::kRtu : ModbusLinkOptions::Transport::kTcp;
    link.port = server->port();
    link.serial_device = server->rtu_path();
    link.baud = options.rtu_baud;
    link.response_timeout_ms = 100;
    link.retry_backoff_ms = 2;
  }
};

LightPattern Pattern(std::vector<double> levels) { return {std::move(levels)}; }

// One register layout over one transport.
struct MapCase {
  ModbusLightMap::Switch on_off;
  bool intensity;
  bool rtu;

  std::string Name() const {  // coils_intensity_tcp, bitmask_switch_only_rtu, ...
    return std::string(Map(1, on_off, intensity).SwitchName()) + (intensity ? "_intensity" : "_switch_only") +
           (rtu ? "_rtu" : "_tcp");
  }
};

void PrintTo(const MapCase& c, std::ostream* out) { *out << c.Name(); }

class MapTest : public ::testing::TestWithParam<MapCase> {};

TEST_P(MapTest, PatternReachesTheWorldAndReadsBack) {
  const auto [on_off, intensity, rtu] = GetParam();
  const ModbusLightMap map = Map(20, on_off, intensity);  // 20 > 16: two bitmask registers
  Bench bench(map, rtu);
  ModbusLightController lights("dome", bench.link, map);
  ASSERT_TRUE(lights.Open().ok()) << lights.Open().ToString();
  std::vector<double> levels(20, 0.0);
  levels[0] = 1.0;
  levels[7] = 0.25;
  levels[17] = 0.5;
  const std::uint64_t before = lights.link().requests();
  const Status set = lights.SetPattern(Pattern(levels));
  ASSERT_TRUE(set.ok()) << set.ToString();
  // Write-multiple: at most one request per register kind, plus the verifying reads.
  const int kinds = (on_off != ModbusLightMap::Switch::kNone) + intensity;
  EXPECT_EQ(lights.link().requests() - before, static_cast<std::uint64_t>(2 * kinds));

  const std::vector<double> expected = map.Quantise(Pattern(levels)).levels;
  const std::vector<double> world = bench.world->levels();
  for (int i = 0; i < 20; ++i) EXPECT_NEAR(world[i], expected[i], 1e-9) << "channel " << i;
  auto back = lights.ReadBack();
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back->levels, expected);
  if (!intensity) {
    EXPECT_EQ(world[7], 1.0);  // on/off only: any level lights fully
  }

  ASSERT_TRUE(lights.Close().ok());
  for (double level : bench.world->levels()) EXPECT_EQ(level, 0.0);  // Close leaves the dome dark
}

INSTANTIATE_TEST_SUITE_P(Maps, MapTest,
                         ::testing::Values(MapCase{ModbusLightMap::Switch::kCoils, false, false},
                                           MapCase{ModbusLightMap::Switch::kCoils, true, false},
                                           MapCase{ModbusLightMap::Switch::kBitmask, false, false},
                                           MapCase{ModbusLightMap::Switch::kBitmask, true, false},
                                           MapCase{ModbusLightMap::Switch::kNone, true, false},
                                           MapCase{ModbusLightMap::Switch::kCoils, true, true},
                                           MapCase{ModbusLightMap::Switch::kBitmask, false, true}),
                         [](const ::testing::TestParamInfo<MapCase>& info) { return info.param.Name(); });

TEST(ModbusLights, SimCameraSeesWhatTheModbusClientCommanded) {
  const ModbusLightMap map = Map(4, ModbusLightMap::Switch::kCoils, true);
  Bench bench(map);
  ModbusLightController lights("dome", bench.link, map);
  sim::SimCamera camera("cam", bench.world);
  ASSERT_TRUE(lights.Open().ok());
  ASSERT_TRUE(camera.Open().ok());
  drivers::CameraSettings settings;
  settings.exposure_us = 20000;
  ASSERT_TRUE(camera.Configure(settings).ok());
  ASSERT_TRUE(camera.Start().ok());
  auto mean = [&] {
    EXPECT_TRUE(camera.Trigger().ok());
    auto frame = camera.WaitFrame(1000);
    EXPECT_TRUE(frame.ok());
    double sum = 0;
    for (auto p : frame->pixels) sum += p;
    return sum / frame->pixels.size();
  };
  const double dark = mean();
  ASSERT_TRUE(lights.SetPattern(LightPattern::Single(4, 1, 1.0)).ok());
  const double full = mean();
  ASSERT_TRUE(lights.SetPattern(LightPattern::Single(4, 1, 0.5)).ok());
  const double half = mean();
  EXPECT_GT(full - dark, 20.0);
  EXPECT_NEAR((half - dark) / (full - dark), 0.5, 0.05);
}

TEST(ModbusLights, ExceptionReplyNamesDeviceAndRegister) {
  const ModbusLightMap map = Map(8, ModbusLightMap::Switch::kCoils, true);
  sim::ModbusServerFaults faults;
  faults.exception_addresses = {13};  // coil of channel 3
  Bench bench(map, false, faults);
  ModbusLightController lights("dome7", bench.link, map);
  const Status open = lights.Open();  // Open starts dark: the all-off write already hits the bad coil
  ASSERT_FALSE(open.ok());
  EXPECT_EQ(open.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(open.message().find("dome7"), std::string::npos) << open.message();
  EXPECT_NE(open.message().find("write coils 10..17"), std::string::npos) << open.message();
  EXPECT_NE(open.message().find("Illegal data address"), std::string::npos) << open.message();
  EXPECT_NE(open.message().find("127.0.0.1:" + std::to_string(bench.server->port())), std::string::npos);
}

TEST(ModbusLights, ExceptionRepliesAreNotRetried) {
  const ModbusLightMap map = Map(8, ModbusLightMap::Switch::kCoils, false);
  sim::ModbusServerFaults faults;
  faults.exception_at = {3};  // Open: write(0) + read(1) verify; then write(2), read(3) verify
  Bench bench(map, false, faults);
  ModbusLightController lights("dome", bench.link, map);
  ASSERT_TRUE(lights.Open().ok());
  const Status status = lights.SetPattern(LightPattern::Single(8, 2, 1.0));
  EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(status.message().find("read coils 10..17: Modbus exception"), std::string::npos) << status.message();
  EXPECT_EQ(bench.server->requests(), 4u);
}

TEST(ModbusLights, DroppedConnectionIsRetriedOnAFreshLink) {
  const ModbusLightMap map = Map(8, ModbusLightMap::Switch::kCoils, true);
  sim::ModbusServerFaults faults;
  faults.disconnect_at = {4, 5};  // the intensity write of the first pattern, twice
  Bench bench(map, false, faults);
  ModbusLightController lights("dome", bench.link, map);
  ASSERT_TRUE(lights.Open().ok());
  const Status status = lights.SetPattern(LightPattern::Single(8, 5, 0.75));
  ASSERT_TRUE(status.ok()) << status.ToString();
  EXPECT_NEAR(bench.world->levels()[5], 0.75, 1e-9);
  // The controller power-cycled between commands: the next command reconnects.
  bench.server->DropClients();
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  ASSERT_TRUE(lights.SetPattern(LightPattern::Single(8, 6, 1.0)).ok());
  EXPECT_EQ(bench.world->levels()[6], 1.0);
}

TEST(ModbusLights, UnreachableControllerFailsAfterRetriesNamingTheDevice) {
  const ModbusLightMap map = Map(8, ModbusLightMap::Switch::kCoils, false);
  Bench bench(map);
  ModbusLinkOptions link = bench.link;
  bench.server->Stop();
  link.retries = 2;
  ModbusLightController lights("dome", link, map);
  const Status status = lights.Open();
  EXPECT_EQ(status.code(), StatusCode::kUnavailable);
  EXPECT_NE(status.message().find("light controller dome"), std::string::npos) << status.message();
}

TEST(ModbusLights, RtuTimeoutWhenTheControllerStaysSilent) {
  const ModbusLightMap map = Map(8, ModbusLightMap::Switch::kCoils, false);
  sim::ModbusServerFaults faults;
  faults.disconnect_at = {2, 3, 4, 5};  // silence on every attempt of the first pattern write
  Bench bench(map, true, faults);
  ModbusLinkOptions link = bench.link;
  link.retries = 3;
  ModbusLightController lights("dome", link, map);
  ASSERT_TRUE(lights.Open().ok());
  const Status status = lights.SetPattern(LightPattern::Single(8, 1, 1.0));
  EXPECT_EQ(status.code(), StatusCode::kUnavailable);
  EXPECT_NE(status.message().find("after 4 attempts"), std::string::npos) << status.message();
  EXPECT_NE(status.message().find("rtu " + bench.server->rtu_path()), std::string::npos) << status.message();
  // The next attempt is answered.
  EXPECT_TRUE(lights.SetPattern(LightPattern::Single(8, 1, 1.0)).ok());
}

TEST(ModbusLights, StuckLedIsCaughtByReadBack) {
  const ModbusLightMap map = Map(8, ModbusLightMap::Switch::kCoils, true);
  sim::LightFaults light;
  light.stuck_off_channels = {4};
  Bench bench(map, false, {}, light);
  ModbusLightController lights("dome", bench.link, map);
  ASSERT_TRUE(lights.Open().ok());
  ASSERT_TRUE(lights.SetPattern(LightPattern::Single(8, 3, 1.0)).ok());
  const Status status = lights.SetPattern(LightPattern::Single(8, 4, 1.0));
  EXPECT_EQ(status.code(), StatusCode::kDataLoss);
  EXPECT_NE(status.message().find("channel 4"), std::string::npos) << status.message();
  EXPECT_NE(status.message().find("coil 14"), std::string::npos) << status.message();
  EXPECT_EQ(bench.world->levels()[4], 0.0);
}

TEST(ModbusLights, InvalidMapIsRefusedAtOpen) {
  ModbusLightMap map = Map(8, ModbusLightMap::Switch::kNone, false);
  ModbusLightController lights("dome", ModbusLinkOptions{}, map);
  const Status status = lights.Open();
  EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(status.message().find("coils, a bitmask or intensity"), std::string::npos);
}

// The controller's communication-loss watchdog, armed at Open.
ModbusLightMap WatchedMap() {
  ModbusLightMap map = Map(4, ModbusLightMap::Switch::kCoils, true);
  map.watchdog_address = 300;
  map.watchdog_timeout_ms = 1000;
  return map;
}

TEST(ModbusLights, TheControllerSwitchesOffWhenItsLinkGoesQuiet) {
  const ModbusLightMap map = WatchedMap();
  Bench bench(map);
  ModbusLightController lights("dome", bench.link, map);
  ASSERT_TRUE(lights.Open().ok());
  ASSERT_TRUE(lights.SetPattern(Pattern({0, 1, 0, 0.5})).ok());
  EXPECT_EQ(bench.world->levels()[1], 1.0);
  std::this_thread::sleep_for(std::chrono::milliseconds(1400));  // the owner says nothing for 1.4 s
  EXPECT_EQ(bench.world->levels(), std::vector<double>(4, 0.0));
  EXPECT_EQ(bench.peer->trips(), 1);
  auto back = lights.ReadBack();  // the registers say so too
  ASSERT_TRUE(back.ok());
  EXPECT_TRUE(back->IsDark());
}

TEST(ModbusLights, KeepAliveFromTheSafetyLayerHoldsALongExposure) {
  const ModbusLightMap map = WatchedMap();
  Bench bench(map);
  drivers::LightSafetyOptions safety;
  safety.watchdog_ms = 0;  // the sequencer's watchdog is not what this tests
  drivers::SafeLightController lights(std::make_unique<ModbusLightController>("dome", bench.link, map), safety);
  ASSERT_TRUE(lights.Open().ok());
  ASSERT_TRUE(lights.SetPattern(Pattern({0, 1, 0, 0})).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(1600));  // an exposure longer than the timeout
  EXPECT_EQ(bench.world->levels()[1], 1.0);
  EXPECT_EQ(bench.peer->trips(), 0);
  ASSERT_TRUE(lights.Close().ok());
  EXPECT_EQ(bench.world->levels(), std::vector<double>(4, 0.0));
}

TEST(ModbusLights, AWatchdogRegisterInsideTheLedRegistersIsRefused) {
  ModbusLightMap map = WatchedMap();
  map.watchdog_address = map.intensity_address + 2;
  std::string why;
  EXPECT_FALSE(map.IsValid(&why));
  EXPECT_NE(why.find("overlaps"), std::string::npos) << why;
}

}  // namespace
}  // namespace photorig
