// The Aravis driver against a real GigE Vision peer: Aravis' fake GV camera on
// 127.0.0.1, whose frames the simulator renders from a sim::World.

#include "photorig/drivers/aravis/aravis_camera.h"
#include "photorig/sim/gige/gige_camera.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace photorig {
namespace {

using drivers::AravisCamera;
using drivers::AravisCameraOptions;
using drivers::CameraSettings;
using drivers::TriggerMode;

// A small noise-free world, so a frame is exactly predictable from the render.
std::shared_ptr<sim::World> MakeWorld() {
  sim::WorldConfig config;
  config.scene.shape = sim::Scene::Shape::kSphere;
  config.scene.sphere_radius_mm = 2.5;
  config.camera.width = 72;
  config.camera.height = 56;
  config.camera.pixel_pitch_mm = 0.1;
  config.sensor.shot_noise = false;
  config.sensor.read_noise_e = 0.0;
  const std::pair<Eigen::Vector3d, double> lights[] = {
      {{0.6, 0.0, 0.8}, 1.0}, {{0.0, -0.6, 0.8}, 1.0}, {{0.0, 0.0, 1.0}, 0.7}};
  for (const auto& [direction, irradiance] : lights) {
    sim::Light light;
    light.direction = direction;
    light.irradiance = irradiance;
    config.lights.push_back(light);
  }
  return std::make_shared<sim::World>(config);
}

// Generous: a frame that does come arrives within milliseconds, but on a machine loaded by a
// parallel build the fake's UDP stream can stall for seconds; the expected-timeout cases use short waits.
constexpr int kFrameTimeoutMs = 10000;

sim::GigeFakeCameraOptions FakeOptions(const std::string& serial) {
  sim::GigeFakeCameraOptions options;
  options.serial = serial;
  return options;
}

std::unique_ptr<sim::GigeFakeCamera> StartFake(std::shared_ptr<sim::World> world, sim::GigeFakeCameraOptions options) {
  auto fake = sim::GigeFakeCamera::Start(std::move(world), std::move(options));
  EXPECT_TRUE(fake.ok()) << fake.status().ToString();
  return fake.ok() ? std::move(fake).value() : nullptr;
}

AravisCameraOptions CameraOptions(const std::string& device) {
  AravisCameraOptions options;
  options.device = device;
  options.reconnect_delay_ms = 100;
  return options;
}

CameraSettings Settings(double exposure_us = 4000.0, double gain_db = 0.0) {
  CameraSettings settings;
  settings.bit_depth = 12;
  settings.exposure_us = exposure_us;
  settings.gain_db = gain_db;
  return settings;
}

std::vector<std::uint16_t> Expected(const sim::World& world, int bits, double exposure_us, double gain_db) {
  sim::SensorModel sensor = world.config().sensor;
  sensor.bit_depth = bits;
  return sim::ExposeFrame(sensor, world.RenderRadiance(), exposure_us, gain_db, world.config().seed, 0);
}

TEST(AravisCamera, DiscoversTheFakeAndOpensBySerialAddressOrId) {
  auto world = MakeWorld();
  auto fake = StartFake(world, FakeOptions("DISC1"));
  ASSERT_TRUE(fake);

  const auto cameras = drivers::DiscoverAravisCameras(true);
  const auto it = std::find_if(cameras.begin(), cameras.end(), [](const auto& c) { return c.serial == "DISC1"; });
  ASSERT_NE(it, cameras.end());
  EXPECT_EQ(it->address, "127.0.0.1");
  EXPECT_EQ(it->sensor_width, 72);
  EXPECT_EQ(it->sensor_height, 56);
  EXPECT_NE(std::find(it->pixel_formats.begin(), it->pixel_formats.end(), "Mono12"), it->pixel_formats.end());
  EXPECT_GT(it->exposure_max_us, it->exposure_min_us);

  for (const std::string& selector : {std::string("DISC1"), std::string("127.0.0.1"), it->id}) {
    AravisCamera camera("cam", CameraOptions(selector));
    ASSERT_TRUE(camera.Open().ok()) << selector;
    EXPECT_EQ(camera.device_id(), it->id);
    EXPECT_TRUE(camera.Close().ok());
  }
  AravisCamera missing("cam", CameraOptions("NO-SUCH-SERIAL"));
  const Status status = missing.Open();
  EXPECT_EQ(status.code(), StatusCode::kUnavailable);
  EXPECT_NE(status.message().find("NO-SUCH-SERIAL"), std::string::npos) << status.message();
}

TEST(AravisCamera, SoftwareTriggeredSequenceShowsTheWorldsLights) {
  auto world = MakeWorld();
  auto fake = StartFake(world, FakeOptions("SEQ1"));
  ASSERT_TRUE(fake);
  AravisCamera camera("cam", CameraOptions("SEQ1"));
  ASSERT_TRUE(camera.Open().ok());
  auto adjustments = camera.Configure(Settings());
  ASSERT_TRUE(adjustments.ok()) << adjustments.status().ToString();
  EXPECT_TRUE(adjustments->empty());
  EXPECT_EQ(camera.settings().pixel_format, "Mono12");
  ASSERT_TRUE(camera.Start().ok());

  std::uint64_t previous_id = 0;
  std::vector<std::uint16_t> previous_pixels;
  for (int light = 0; light < 3; ++light) {
    std::vector<double> levels(3, 0.0);
    levels[light] = 1.0;
    world->SetLevels(levels);
    ASSERT_TRUE(camera.Trigger().ok());
    auto frame = camera.WaitFrame(kFrameTimeoutMs);
    ASSERT_TRUE(frame.ok()) << frame.status().ToString();
    EXPECT_EQ(frame->width, 72);
    EXPECT_EQ(frame->height, 56);
    EXPECT_EQ(frame->bit_depth, 12);
    EXPECT_EQ(frame->pixel_format, "Mono12");
    EXPECT_EQ(frame->exposure_us, 4000.0);
    EXPECT_EQ(frame->dropped_before, 0u);
    EXPECT_GT(frame->device_timestamp_ns, 0);
    if (light > 0) {
      EXPECT_EQ(frame->frame_id, previous_id == 65535 ? 1 : previous_id + 1);
    }
    previous_id = frame->frame_id;
    EXPECT_EQ(frame->pixels, Expected(*world, 12, 4000.0, 0.0)) << "light " << light;
    // Each light shows a different shading: the frames are not a fixed pattern.
    EXPECT_GT(*std::max_element(frame->pixels.begin(), frame->pixels.end()), 300);
    EXPECT_NE(frame->pixels, previous_pixels);
    previous_pixels = frame->pixels;
  }
  EXPECT_EQ(camera.statistics().frames, 3u);
  EXPECT_EQ(camera.statistics().dropped, 0u);
  EXPECT_TRUE(camera.Close().ok());
}

// A trigger sent the moment the stream starts must still give its frame: the receive path has to
// exist before the start (a packet ring attached later by the stream's thread loses such frames).
TEST(AravisCamera, FrameTriggeredAsTheStreamStartsArrives) {
  auto world = MakeWorld();
  auto fake = StartFake(world, FakeOptions("RESTART1"));
  ASSERT_TRUE(fake);
  AravisCamera camera("cam", CameraOptions("RESTART1"));
  ASSERT_TRUE(camera.Open().ok());
  ASSERT_TRUE(camera.Configure(Settings(300.0)).ok());
  constexpr int kCycles = 12;
  for (int cycle = 0; cycle < kCycles; ++cycle) {
    ASSERT_TRUE(camera.Start().ok());
    ASSERT_TRUE(camera.Trigger().ok());
    auto frame = camera.WaitFrame(kFrameTimeoutMs);
    ASSERT_TRUE(frame.ok()) << "cycle " << cycle << ": " << frame.status().ToString();
    EXPECT_EQ(frame->pixels, Expected(*world, 12, 300.0, 0.0)) << "cycle " << cycle;
    ASSERT_TRUE(camera.Stop().ok());
  }
  EXPECT_EQ(camera.statistics().frames, static_cast<std::uint64_t>(kCycles));
  EXPECT_EQ(camera.statistics().timeouts, 0u);
}

TEST(AravisCamera, ExposureAndGainRoundTripWithReportedAdjustments) {
  auto world = MakeWorld();
  world->SetLevels({0.0, 0.0, 1.0});
  auto fake = StartFake(world, FakeOptions("EXPO1"));
  ASSERT_TRUE(fake);
  AravisCamera camera("cam", CameraOptions("EXPO1"));
  ASSERT_TRUE(camera.Open().ok());

  // The fake stores exposure in whole microseconds and gain as an integer 0..10.
  auto adjustments = camera.Configure(Settings(2500.4, 3.4));
  ASSERT_TRUE(adjustments.ok()) << adjustments.status().ToString();
  ASSERT_EQ(adjustments->size(), 2u);
  EXPECT_EQ(adjustments.value()[0].field, "exposure_us");
  EXPECT_DOUBLE_EQ(adjustments.value()[0].applied, 2500.0);
  EXPECT_EQ(adjustments.value()[1].field, "gain_db");
  EXPECT_DOUBLE_EQ(adjustments.value()[1].applied, 3.0);
  EXPECT_DOUBLE_EQ(camera.settings().exposure_us, 2500.0);

  auto clamped = camera.Configure(Settings(5.0, 40.0));
  ASSERT_TRUE(clamped.ok());
  EXPECT_DOUBLE_EQ(camera.settings().exposure_us, 10.0);  // the fake's minimum
  EXPECT_DOUBLE_EQ(camera.settings().gain_db, 10.0);      // and maximum gain

  // The device renders with what it was given: twice the exposure, twice the signal above black.
  double means[2];
  const double exposures[2] = {1500.0, 3000.0};
  for (int i = 0; i < 2; ++i) {
    ASSERT_TRUE(camera.Configure(Settings(exposures[i], 0.0)).ok());
    ASSERT_TRUE(camera.Start().ok());
    ASSERT_TRUE(camera.Trigger().ok());
    auto frame = camera.WaitFrame(kFrameTimeoutMs);
    ASSERT_TRUE(frame.ok()) << frame.status().ToString();
    EXPECT_DOUBLE_EQ(frame->exposure_us, exposures[i]);
    double sum = 0;
    for (auto v : frame->pixels) sum += v - world->config().sensor.black_level_dn;
    means[i] = sum / frame->pixels.size();
    ASSERT_TRUE(camera.Stop().ok());
  }
  EXPECT_NEAR(means[1] / means[0], 2.0, 0.02);
}

TEST(AravisCamera, PixelFormatsArriveAsSixteenBitSamples) {
  auto world = MakeWorld();
  world->SetLevels({1.0, 1.0, 0.0});
  auto fake = StartFake(world, FakeOptions("FMT1"));
  ASSERT_TRUE(fake);
  AravisCamera camera("cam", CameraOptions("FMT1"));
  ASSERT_TRUE(camera.Open().ok());

  struct Case {
    int bit_depth;
    std::string format;  // requested
    std::string applied;
    int bits;
  };
  for (const Case& c : {Case{8, "", "Mono8", 8}, Case{10, "", "Mono10", 10}, Case{16, "", "Mono16", 16},
                        Case{14, "", "Mono16", 16}, Case{12, "BayerRG8", "BayerRG8", 8}}) {
    CameraSettings settings = Settings(300.0);
    settings.bit_depth = c.bit_depth;
    settings.pixel_format = c.format;
    auto adjustments = camera.Configure(settings);
    ASSERT_TRUE(adjustments.ok()) << c.applied << ": " << adjustments.status().ToString();
    EXPECT_EQ(camera.settings().pixel_format, c.applied);
    EXPECT_EQ(camera.settings().bit_depth, c.bits);
    EXPECT_EQ(adjustments->size(), c.bit_depth == c.bits ? 0u : 1u) << c.applied;
    ASSERT_TRUE(camera.Start().ok());
    ASSERT_TRUE(camera.Trigger().ok());
    auto frame = camera.WaitFrame(kFrameTimeoutMs);
    ASSERT_TRUE(frame.ok()) << frame.status().ToString();
    EXPECT_EQ(frame->bit_depth, c.bits);
    EXPECT_EQ(frame->pixels, Expected(*world, c.bits, 300.0, 0.0)) << c.applied;
    ASSERT_TRUE(camera.Stop().ok());
  }
  CameraSettings rgb = Settings();
  rgb.pixel_format = "RGB8";
  auto rejected = camera.Configure(rgb);
  EXPECT_EQ(rejected.status().code(), StatusCode::kInvalidArgument);
}

TEST(AravisCamera, TimeoutsAndIllegalTransitionsAreErrors) {
  auto world = MakeWorld();
  auto fake = StartFake(world, FakeOptions("TMO1"));
  ASSERT_TRUE(fake);
  AravisCamera camera("cam", CameraOptions("TMO1"));
  EXPECT_EQ(camera.Trigger().code(), StatusCode::kFailedPrecondition);
  ASSERT_TRUE(camera.Open().ok());
  EXPECT_EQ(camera.Start().code(), StatusCode::kFailedPrecondition);
  ASSERT_TRUE(camera.Configure(Settings(1000.0)).ok());
  EXPECT_EQ(camera.Trigger().code(), StatusCode::kFailedPrecondition);
  ASSERT_TRUE(camera.Start().ok());
  // The bound on one frame follows the exposure and the readout of the payload.
  EXPECT_GE(camera.FrameTimeoutMs(), 1 + 200);
  auto frame = camera.WaitFrame(150);  // never triggered
  EXPECT_EQ(frame.status().code(), StatusCode::kTimeout);
  EXPECT_NE(frame.status().message().find("triggered"), std::string::npos) << frame.status().message();
  EXPECT_EQ(camera.statistics().timeouts, 1u);
  EXPECT_EQ(camera.statistics().reconnects, 0u);  // a healthy link is not "lost"
  EXPECT_TRUE(camera.Close().ok());
  EXPECT_EQ(camera.state(), drivers::Camera::State::kClosed);
}

TEST(AravisCamera, HardwareTriggerArmsAnOfferedLine) {
  auto world = MakeWorld();
  auto fake = StartFake(world, FakeOptions("HW1"));
  ASSERT_TRUE(fake);
  AravisCamera camera("cam", CameraOptions("HW1"));
  ASSERT_TRUE(camera.Open().ok());
  CameraSettings settings = Settings(1000.0);
  settings.trigger = TriggerMode::kHardware;
  settings.trigger_line = "Line7";
  auto rejected = camera.Configure(settings);
  ASSERT_EQ(rejected.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(rejected.status().message().find("Line0"), std::string::npos) << rejected.status().message();

  settings.trigger_line = "Line0";
  ASSERT_TRUE(camera.Configure(settings).ok());
  ASSERT_TRUE(camera.Start().ok());
  EXPECT_EQ(camera.Trigger().code(), StatusCode::kFailedPrecondition);  // no software trigger in hardware mode
  auto frame = camera.WaitFrame(200);  // armed; no pulse arrives on the fake's Line0
  EXPECT_EQ(frame.status().code(), StatusCode::kTimeout);
  EXPECT_NE(frame.status().message().find("Line0"), std::string::npos) << frame.status().message();
}

TEST(AravisCamera, LostPacketsAreReportedNeverDeliveredAsFrames) {
  auto world = MakeWorld();
  world->SetLevels({1.0, 0.0, 0.0});
  sim::GigeFakeCameraOptions fake_options = FakeOptions("LOSS1");
  fake_options.lost_packet_ratio = 0.2;  // a frame is ~7 packets: most frames lose one
  auto fake = StartFake(world, fake_options);
  ASSERT_TRUE(fake);
  AravisCameraOptions options = CameraOptions("LOSS1");
  options.packet_resend = false;
  AravisCamera camera("cam", options);
  ASSERT_TRUE(camera.Open().ok());
  ASSERT_TRUE(camera.Configure(Settings(1000.0)).ok());
  ASSERT_TRUE(camera.Start().ok());
  const auto expected = Expected(*world, 12, 1000.0, 0.0);
  int lossy = 0;
  for (int i = 0; i < 12; ++i) {
    ASSERT_TRUE(camera.Trigger().ok());
    auto frame = camera.WaitFrame(300);
    if (frame.ok()) {
      EXPECT_EQ(frame->pixels, expected) << "a frame delivered as complete must be intact";
      continue;
    }
    ++lossy;
    EXPECT_TRUE(frame.status().code() == StatusCode::kDataLoss || frame.status().code() == StatusCode::kTimeout)
        << frame.status().ToString();
  }
  EXPECT_GE(lossy, 6);
  const auto& stats = camera.statistics();
  EXPECT_EQ(stats.incomplete + stats.timeouts, static_cast<std::uint64_t>(lossy));
  EXPECT_EQ(stats.frames, static_cast<std::uint64_t>(12 - lossy));
}

TEST(AravisCamera, ReconnectsAndReappliesSettingsWhenTheCameraRestarts) {
  auto world = MakeWorld();
  world->SetLevels({0.0, 1.0, 0.0});
  auto fake = StartFake(world, FakeOptions("RECON1"));
  ASSERT_TRUE(fake);
  AravisCamera camera("cam", CameraOptions("RECON1"));
  ASSERT_TRUE(camera.Open().ok());
  ASSERT_TRUE(camera.Configure(Settings(2000.0, 2.0)).ok());
  ASSERT_TRUE(camera.Start().ok());
  ASSERT_TRUE(camera.Trigger().ok());
  const auto first = camera.WaitFrame(kFrameTimeoutMs);
  ASSERT_TRUE(first.ok()) << first.status().ToString();

  // The camera power-cycles: a new device with default registers (Mono8, 10 ms, gain 0) and no controller.
  fake.reset();
  fake = StartFake(world, FakeOptions("RECON1"));
  ASSERT_TRUE(fake);

  ASSERT_TRUE(camera.Trigger().ok());
  auto frame = camera.WaitFrame(kFrameTimeoutMs);
  ASSERT_TRUE(frame.ok()) << frame.status().ToString();
  EXPECT_EQ(camera.statistics().reconnects, 1u);
  EXPECT_EQ(frame->pixel_format, "Mono12");
  EXPECT_EQ(frame->pixels, Expected(*world, 12, 2000.0, 2.0)) << "settings were re-applied to the new device";
}

TEST(AravisCamera, GivesUpAfterBoundedReconnectAttempts) {
  auto world = MakeWorld();
  auto fake = StartFake(world, FakeOptions("GONE1"));
  ASSERT_TRUE(fake);
  AravisCameraOptions options = CameraOptions("GONE1");
  options.reconnect_attempts = 1;
  AravisCamera camera("cam", options);
  ASSERT_TRUE(camera.Open().ok());
  ASSERT_TRUE(camera.Configure(Settings(1000.0)).ok());
  ASSERT_TRUE(camera.Start().ok());
  fake.reset();  // unplugged for good

  Status status = camera.Trigger();
  if (status.ok()) status = camera.WaitFrame(300).status();
  EXPECT_EQ(status.code(), StatusCode::kUnavailable) << status.ToString();
  EXPECT_NE(status.message().find("gave up after 1 reconnect attempts"), std::string::npos) << status.message();
  EXPECT_TRUE(camera.Close().ok());
}

}  // namespace
}  // namespace photorig
