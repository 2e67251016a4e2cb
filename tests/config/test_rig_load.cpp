// Everything a rig file says is checked when it is loaded, driver settings and
// the simulated scene included: no configuration error waits for the devices.

#include "photorig/config/modules.h"
#include "photorig/config/rig.h"
#include "photorig/config/sim.h"
#include "config_error_check.h"
#include "test_support.h"

#include <gtest/gtest.h>

#include <string>

namespace photorig::config {
namespace {

using photorig::testing::SourceDir;
using photorig::testing::TempDir;

// A two-LED rig; `lights` and `camera` are the bodies of those sections.
std::string Rig(const std::string& lights, const std::string& camera, const std::string& sim = "  seed: 1\n") {
  return "rig: {name: r}\n"
         "lights:\n" + lights +
         "  leds:\n"
         "    - {direction: [0, 0, 1]}\n"
         "    - {direction: [0.6, 0, 0.8]}\n"
         "camera:\n" + camera +
         "  width: 40\n"
         "  height: 30\n"
         "sim:\n" + sim;
}

const char* kSimLights = "  driver: sim\n";
const char* kSimCamera = "  driver: sim\n";

void ExpectLoadError(const std::string& text, int line, int column, const std::string& key,
                     const std::string& fragment) {
  TempDir dir;
  const std::string path = dir.Write("rig.yaml", text);
  SCOPED_TRACE(text);
  photorig::testing::ExpectConfigErrorAt([&] { LoadRigConfig(path); }, path, line, column, fragment, key);
}

TEST(RigLoad, ModbusOptionsAreParsedIntoTypedSettings) {
  const RigConfig rig = LoadRigConfig(SourceDir() + "/config/rigs/sim-dome-modbus.yaml");
  ASSERT_TRUE(rig.lights.modbus.has_value());
  const ModbusLightsOptions& modbus = *rig.lights.modbus;
  EXPECT_TRUE(modbus.simulated);
  EXPECT_EQ(modbus.map.channels, static_cast<int>(rig.lights.leds.size()));
  EXPECT_TRUE(modbus.map.intensity);
  EXPECT_EQ(modbus.map.intensity_address, 100);
  EXPECT_EQ(modbus.map.full_scale, 1000);
  EXPECT_EQ(modbus.link.retries, 3);
  EXPECT_EQ(rig.lights.safety.defaults.max_on_ms, 2000.0);
  EXPECT_EQ(rig.lights.safety.watchdog_ms, 5000.0);
  EXPECT_EQ(modbus.map.watchdog_address, 200);
  EXPECT_EQ(modbus.map.watchdog_timeout_ms, 2000);
}

// camera.calibration (written by `photorig calibrate camera`) records where a
// pinhole lens came from: checked, and refused beside an orthographic camera.
TEST(RigLoad, ALensCalibrationRecordIsCheckedAndNeedsAPinhole) {
  const std::string record =
      "  calibration: {date: 2026-11-29T10:30:00Z, rms_px: 0.05, tilt_deg: 0.1, board: {inner_corners: [9, 6], "
      "square_mm: 10}, plane_image: a.png, images: [a.png, b.png]}\n";
  const std::string pinhole = "  driver: sim\n  projection: pinhole\n  pinhole: {fx_px: 50, distance_mm: 300}\n";
  TempDir dir;
  EXPECT_NO_THROW(LoadRigConfig(dir.Write("pinhole.yaml", Rig(kSimLights, pinhole + record))));
  std::string typo = record;
  typo.replace(typo.find("rms_px"), 6, "rms_pix");
  EXPECT_THROW(LoadRigConfig(dir.Write("typo.yaml", Rig(kSimLights, pinhole + typo))), ConfigError);
  std::string negative = record;
  negative.replace(negative.find("0.05"), 4, "-1.0");
  EXPECT_THROW(LoadRigConfig(dir.Write("negative.yaml", Rig(kSimLights, pinhole + negative))), ConfigError);
  const std::string orthographic = std::string(kSimCamera) + "  pixel_pitch_mm: 0.1\n";
  EXPECT_THROW(LoadRigConfig(dir.Write("orthographic.yaml", Rig(kSimLights, orthographic + record))), ConfigError);
}

// An LED's `channel` other than its place in the list would be ignored and
// light the wrong LED: refused, naming the order photorig drives.
TEST(RigLoad, AnLedChannelOtherThanItsPlaceIsRefused) {
  std::string text = Rig(kSimLights, kSimCamera);
  text.replace(text.find("{direction: [0.6, 0, 0.8]}"), 26, "{direction: [0.6, 0, 0.8], channel: 7}");
  ExpectLoadError(text, 6, 43, "lights.leds[1].channel", "list the LEDs in output order");
  text.replace(text.find("channel: 7"), 10, "channel: 1");
  TempDir dir;
  EXPECT_NO_THROW(LoadRigConfig(dir.Write("rig.yaml", text)));
}

#if PHOTORIG_HAVE_DRIVERS_GPIO
TEST(RigLoad, AGpioHeartbeatLineIsParsedAndMayNotDriveAnLed) {
  TempDir dir;
  const RigConfig rig = LoadRigConfig(dir.Write(
      "rig.yaml", Rig("  driver: gpio\n  options: {lines: [4, 5], heartbeat: {offset: 9, active_low: true}}\n", kSimCamera)));
  ASSERT_TRUE(rig.lights.gpio && rig.lights.gpio->heartbeat);
  EXPECT_EQ(rig.lights.gpio->heartbeat->chip, "gpiochip0");
  EXPECT_EQ(rig.lights.gpio->heartbeat->offset, 9u);
  EXPECT_TRUE(rig.lights.gpio->heartbeat->active_low);
  ExpectLoadError(Rig("  driver: gpio\n  options: {lines: [4, 5], heartbeat: {offset: 5}}\n", kSimCamera), 4, 48,
                  "lights.options.heartbeat.offset", "also drives an LED");
}
#endif

TEST(RigLoad, ABadDriverOptionFailsTheLoadWithItsPosition) {
  const std::string lights =
      "  driver: modbus-tcp\n"
      "  options:\n"
      "    host: 192.0.2.7\n"
      "    response_timeout_ms: 0\n";
  ExpectLoadError(Rig(lights, kSimCamera), 6, 26, "lights.options.response_timeout_ms", "must be within [1, 60000]");
  const std::string map =
      "  driver: modbus-tcp\n"
      "  options: {host: 192.0.2.7, map: {on_off: relays}}\n";
  ExpectLoadError(Rig(map, kSimCamera), 4, 44, "lights.options.map.on_off", "unknown 'relays'");
  const std::string safety =
      "  driver: modbus-rtu\n"
      "  options: {device: /dev/ttyUSB0, safety: {max_duty: 1.5}}\n";
  ExpectLoadError(Rig(safety, kSimCamera), 4, 43, "lights.options.safety", "max_duty");
  // Served by this process: needs the World, which only a sim: section makes.
  std::string served = Rig("  driver: modbus-tcp\n  options: {host: sim}\n", kSimCamera);
  served = served.substr(0, served.rfind("sim:\n"));
  ExpectLoadError(served, 4, 12, "lights.options", "needs the rig's sim: section");
}

TEST(RigLoad, ABadSimulatedSceneFailsTheLoadWithItsPosition) {
  ExpectLoadError(Rig(kSimLights, kSimCamera, "  scene: {shape: sphere, radius: 3}\n"), 12, 26, "sim.scene.radius",
                  "unknown key 'radius'");
  ExpectLoadError(Rig(kSimLights, kSimCamera, "  scene: {shape: sphere, brdf: {model: ggx, roughness: 2}}\n"), 12,
                  32, "sim.scene.brdf", "roughness must lie in (0, 1]");
  ExpectLoadError(Rig(kSimLights, kSimCamera, "  scene: {shape: mirror_sphere, radius_mm: 1, centres_mm: [[0, 0], [1, 0]]}\n"),
                  12, 59, "sim.scene.centres_mm", "overlap");
  ExpectLoadError(Rig(kSimLights, kSimCamera, "  scene: {shape: bumps, centres_mm: [[0, 0]]}\n"), 12, 37,
                  "sim.scene.centres_mm", "only sphere shapes");
}

TEST(RigLoad, SceneDefaultsAreSizedToTheRigsFrame) {
  TempDir dir;
  const RigConfig rig = LoadRigConfig(dir.Write("rig.yaml", Rig(kSimLights, kSimCamera, "  scene: {shape: sphere}\n")));
  EXPECT_DOUBLE_EQ(FrameWidthMm(rig), 40 * 0.1);
  EXPECT_DOUBLE_EQ(rig.sim->scene.sphere_radius_mm, 0.45 * 40 * 0.1);
}

TEST(RigLoad, APinholeCameraTakesOpenCvIntrinsicsAndTheSimulatorRendersThem) {
  TempDir dir;
  const RigConfig rig = LoadRigConfig(dir.Write(
      "rig.yaml", Rig(kSimLights, "  driver: sim\n  projection: pinhole\n"
                                  "  pinhole: {fx_px: 50, distortion: [-0.1, 0.02, 0, 0], distance_mm: 100}\n")));
  const solvers::camera::Camera camera = rig.camera.Geometry();
  ASSERT_TRUE(camera.IsPinhole());
  EXPECT_EQ(camera.pinhole.fy_px, 50.0);                    // fy defaults to fx
  EXPECT_EQ(camera.pinhole.cx_px, 19.5);                    // the middle of 40 pixel centres 0 .. 39
  EXPECT_EQ(camera.pinhole.cy_px, 14.5);
  EXPECT_EQ(camera.pinhole.distortion[1], 0.02);
  EXPECT_EQ(camera.pinhole.distortion[4], 0.0);             // k3 may be left out
  EXPECT_DOUBLE_EQ(rig.camera.pixel_pitch_mm, 100.0 / 50.0);  // the pixel on the sample plane
  const sim::WorldConfig world = MakeWorldConfig(rig, rig.sim->scene);
  EXPECT_EQ(world.camera.projection, sim::CameraModel::Projection::kPinhole);
  EXPECT_EQ(world.camera.principal_x(), 20.0);              // measured from the image's corner
  EXPECT_EQ(world.camera.distortion[0], -0.1);

  const RigConfig shipped = LoadRigConfig(SourceDir() + "/config/rigs/sim-dome-near.yaml");
  EXPECT_TRUE(shipped.camera.Geometry().IsPinhole());
  EXPECT_NEAR(shipped.camera.Geometry().HorizontalFieldOfViewDeg(), 30.0, 0.01);
  for (const LedConfig& led : shipped.lights.leds) ASSERT_TRUE(led.position_mm.has_value()) << led.id;
}

TEST(RigLoad, APinholeCameraRefusesAPixelPitchAndAnUnknownProjectionIsNamed) {
  ExpectLoadError(Rig(kSimLights, "  driver: sim\n  projection: pinhole\n  pinhole: {fx_px: 50, distance_mm: 100}\n"
                                  "  pixel_pitch_mm: 0.2\n"),
                  11, 19, "camera.pixel_pitch_mm", "follows from pinhole: fx_px and distance_mm");
  ExpectLoadError(Rig(kSimLights, "  driver: sim\n  projection: fisheye\n"), 9, 15, "camera.projection",
                  "'fisheye' is no projection (expected");
  ExpectLoadError(Rig(kSimLights, "  driver: sim\n  projection: pinhole\n  pinhole: {fx_px: 50, distance_mm: -3}\n"),
                  10, 37, "camera.pinhole.distance_mm", "must lie in");
}

// A simulated camera takes no options; simulated lights take only their safety limits.
TEST(RigLoad, OptionsOnASimulatedDeviceAreRefused) {
  ExpectLoadError(Rig(kSimLights, "  driver: sim\n  options: {host: sim}\n"), 9, 12, "camera.options",
                  "the simulated camera takes no options");
  ExpectLoadError(Rig("  driver: sim\n  options: {host: sim}\n", kSimCamera), 4, 13, "lights.options.host",
                  "unknown key 'host'");
}

// A driver whose module this build left out is still known by name; a rig
// naming it does not load. With the module, its options are parsed at load.
TEST(RigLoad, ADriverLeftOutOfTheBuildIsRefusedByName) {
  const std::string camera = "  driver: aravis\n  options: {device: cam7, buffer_count: 6}\n";
  const std::string text = Rig(kSimLights, camera);
#if !PHOTORIG_HAVE_DRIVERS_ARAVIS
  ExpectLoadError(text, 8, 11, "camera.driver", "driver 'aravis' was left out of this build (PHOTORIG_SKIP_MODULES)");
#else
  TempDir dir;
  const RigConfig rig = LoadRigConfig(dir.Write("rig.yaml", text));
  ASSERT_TRUE(rig.camera.aravis.has_value());
  EXPECT_EQ(rig.camera.aravis->camera.device, "cam7");
  EXPECT_EQ(rig.camera.aravis->camera.buffer_count, 6);
  ExpectLoadError(Rig(kSimLights, "  driver: aravis\n  options: {buffer_count: 0}\n"), 9, 12, "camera.options",
                  "buffer_count");
#endif
}

TEST(RigLoad, AnUnknownDriverListsTheOnesThisBuildHas) {
  ExpectLoadError(Rig("  driver: dmx\n", kSimCamera), 3, 11, "lights.driver", "unknown driver 'dmx' (available: sim, ");
}

}  // namespace
}  // namespace photorig::config
