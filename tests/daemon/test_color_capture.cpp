// Colour capture end to end: the Bayer mosaic and its demosaicing, raw frames
// stored as the camera produced them with the pattern recorded, colour
// photometric stereo on the simulated dome checked against the paints' true
// colours after calibrating the simulated camera on its chart, RGB DiLiGenT
// folders, and colour model files that are wrong.

#include "photorig/solvers/color/colorimetry.h"
#include "photorig/config/sim.h"
#include "photorig/daemon/pipelines/color_stack.h"
#include "photorig/daemon/pipelines/diligent.h"
#include "photorig/daemon/io/image_io.h"
#include "photorig/daemon/pipelines/ps_pipeline.h"
#include "photorig/config/rig.h"
#include "photorig/config/sim.h"
#include "photorig/config/yaml_node.h"
#include "photorig/daemon/service/run.h"
#include "photorig/daemon/capture/run_store.h"
#include "photorig/sim/devices.h"
#include "photorig/sim/world.h"
#include "test_support.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <filesystem>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
using solvers::color::DemosaicMethod;
using testing::TempDir;

std::string SourceDir() {
  const char* dir = std::getenv("PHOTORIG_SOURCE_DIR");
  return dir ? dir : PHOTORIG_SOURCE_DIR_FALLBACK;
}

// R, G, B planes that are linear ramps in x and y: bilinear demosaicing
// reproduces a linear function exactly away from the border.
std::array<cv::Mat, 3> RampPlanes(int size) {
  std::array<cv::Mat, 3> planes;
  const double slopes[3][2] = {{90.0, 20.0}, {40.0, 60.0}, {10.0, 110.0}};
  for (int c = 0; c < 3; ++c) {
    planes[c].create(size, size, CV_32F);
    for (int y = 0; y < size; ++y)
      for (int x = 0; x < size; ++x)
        planes[c].at<float>(y, x) = static_cast<float>(1000.0 * (c + 1) + slopes[c][0] * x + slopes[c][1] * y);
  }
  return planes;
}

TEST(BayerMosaic, DemosaicingAMosaicOfLinearRampsGivesThemBackForEveryPattern) {
  constexpr int kSize = 32;
  const std::array<cv::Mat, 3> planes = RampPlanes(kSize);
  for (const std::string pattern : {"RGGB", "BGGR", "GRBG", "GBRG"}) {
    cv::Mat raw;
    sim::MosaicOf(planes, pattern).convertTo(raw, CV_16U);
    // Each site holds its own filter's channel.
    const std::string filters = pattern;
    for (int y = 0; y < 2; ++y)
      for (int x = 0; x < 2; ++x) {
        const int c = filters[y * 2 + x] == 'R' ? 0 : filters[y * 2 + x] == 'G' ? 1 : 2;
        EXPECT_EQ(raw.at<std::uint16_t>(y + 4, x + 4), static_cast<std::uint16_t>(planes[c].at<float>(y + 4, x + 4)))
            << pattern;
      }
    for (const DemosaicMethod method : {DemosaicMethod::kBilinear, DemosaicMethod::kEdgeAware}) {
      const cv::Mat rgb = DemosaicToRgb(raw, pattern, method);
      ASSERT_EQ(rgb.type(), CV_16UC3);
      double worst = 0.0;
      for (int y = 2; y < kSize - 2; ++y)
        for (int x = 2; x < kSize - 2; ++x)
          for (int c = 0; c < 3; ++c)
            worst = std::max(worst, std::abs(rgb.at<cv::Vec3w>(y, x)[c] - static_cast<double>(planes[c].at<float>(y, x))));
      // Bilinear is exact on ramps (to the rounding of the 16-bit result);
      // edge-aware interpolates along one direction, exact on a ramp too.
      EXPECT_LE(worst, 1.0) << pattern << " " << DemosaicMethodName(method);
    }
  }
}

TEST(BayerMosaic, AWrongPatternSwapsRedAndBlue) {
  const std::array<cv::Mat, 3> planes = RampPlanes(16);
  cv::Mat raw;
  sim::MosaicOf(planes, "RGGB").convertTo(raw, CV_16U);
  const cv::Vec3w right = DemosaicToRgb(raw, "RGGB", DemosaicMethod::kBilinear).at<cv::Vec3w>(8, 8);
  const cv::Vec3w wrong = DemosaicToRgb(raw, "BGGR", DemosaicMethod::kBilinear).at<cv::Vec3w>(8, 8);
  EXPECT_NEAR(wrong[0], right[2], 60);  // within one pixel's slope: the sites differ by one
  EXPECT_NEAR(wrong[2], right[0], 120);
  EXPECT_THROW(DemosaicToRgb(raw, "RGBG", DemosaicMethod::kBilinear), std::invalid_argument);
}

TEST(PixelFormats, BayerAndRgbFormatsNameTheirMosaicAndBits) {
  EXPECT_EQ(drivers::MosaicOfPixelFormat("BayerRG12"), "RGGB");
  EXPECT_EQ(drivers::MosaicOfPixelFormat("BayerGR8"), "GRBG");
  EXPECT_EQ(drivers::MosaicOfPixelFormat("BayerGB16"), "GBRG");
  EXPECT_EQ(drivers::MosaicOfPixelFormat("BayerBG10"), "BGGR");
  EXPECT_EQ(drivers::MosaicOfPixelFormat("Mono12"), "mono");
  EXPECT_EQ(drivers::MosaicOfPixelFormat("RGB16"), "RGB");
  EXPECT_EQ(drivers::MosaicOfPixelFormat("RGB12"), "");
  EXPECT_EQ(drivers::MosaicOfPixelFormat("BayerRG13"), "");
  EXPECT_EQ(drivers::BitsOfPixelFormat("BayerBG12"), 12);
}

// The simulated colour camera on the colour rig, showing a uniform red sphere.
struct ColourCamera {
  config::RigConfig rig = config::LoadRigConfig(SourceDir() + "/config/rigs/sim-dome-colour.yaml");
  std::shared_ptr<sim::World> world;
  std::unique_ptr<sim::SimCamera> camera;

  ColourCamera() {
    sim::Scene scene = rig.sim->scene;
    scene.albedo.pattern = sim::AlbedoTexture::Pattern::kUniform;
    scene.albedo.paints = {"red", "red"};
    world = std::make_shared<sim::World>(config::MakeWorldConfig(rig, scene));
    camera = std::make_unique<sim::SimCamera>("cam", world);
    std::vector<double> levels(rig.lights.leds.size(), 0.0);
    levels[0] = 1.0;
    world->SetLevels(levels);
  }

  drivers::Frame Capture() {
    EXPECT_TRUE(camera->Open().ok());
    drivers::CameraSettings settings;
    settings.bit_depth = rig.camera.bit_depth;
    settings.pixel_format = rig.camera.pixel_format;
    settings.exposure_us = rig.camera.exposure_us;
    EXPECT_TRUE(camera->Configure(settings).ok());
    EXPECT_TRUE(camera->Start().ok());
    EXPECT_TRUE(camera->Trigger().ok());
    auto frame = camera->WaitFrame(1000);
    EXPECT_TRUE(frame.ok());
    return frame.value();
  }
};

TEST(ColourCapture, RawBayerFramesAreStoredByteForByteWithThePatternRecorded) {
  ColourCamera colour;
  const drivers::Frame frame = colour.Capture();
  EXPECT_EQ(frame.pixel_format, "BayerRG12");
  ASSERT_EQ(frame.pixels.size(), static_cast<std::size_t>(frame.width) * frame.height);
  // Behind an RGGB filter a red sphere is brightest at the red sites.
  const int y = frame.height / 2 & ~1, x = frame.width / 2 & ~1;
  const auto at = [&](int yy, int xx) { return frame.pixels[static_cast<std::size_t>(yy) * frame.width + xx]; };
  EXPECT_GT(at(y, x), 2 * at(y + 1, x + 1));  // R against B
  EXPECT_GT(at(y, x), at(y, x + 1));          // R against G

  TempDir dir;
  RunManifest header;
  header.run_id = "colour";
  header.width = frame.width;
  header.height = frame.height;
  header.bit_depth = frame.bit_depth;
  header.mosaic = colour.rig.camera.mosaic;
  header.pixel_format = colour.rig.camera.pixel_format;
  header.lights.resize(1);  // the LED the frame names
  const std::string run = (dir.path() / "run").string();
  RunWriter writer(run, header);
  config::CaptureStep step;
  step.kind = config::CaptureStep::Kind::kLight;
  step.label = "0000_led00";
  step.led = 0;
  step.pattern = std::make_shared<const drivers::LightPattern>(drivers::LightPattern{{1.0}});
  writer.WriteFrame(step, frame);
  writer.Finish({CaptureStatus::kComplete, "", 1, 1});

  const RunManifest manifest = LoadRunManifest(run);
  EXPECT_EQ(manifest.mosaic, "RGGB");
  EXPECT_EQ(manifest.pixel_format, "BayerRG12");
  EXPECT_EQ(manifest.frames.at(0).pixel_format, "BayerRG12");
  const cv::Mat stored = cv::imread(run + "/" + manifest.frames.at(0).file, cv::IMREAD_UNCHANGED);
  ASSERT_EQ(stored.type(), CV_16UC1);  // the mosaic, not a demosaiced image
  ASSERT_TRUE(stored.isContinuous());
  EXPECT_EQ(std::memcmp(stored.data, frame.pixels.data(), frame.pixels.size() * 2), 0);
}

TEST(ColourCapture, RunsWithoutAMosaicLoadAsMonochrome) {
  RunManifest header;
  header.width = 8;
  header.height = 6;
  header.bit_depth = 12;
  nlohmann::json manifest = ToJson(header);
  manifest["camera"].erase("mosaic");
  manifest["camera"].erase("pixel_format");
  EXPECT_EQ(RunManifestFromJson(manifest).mosaic, "mono");
  manifest["camera"]["mosaic"] = "RGBW";
  EXPECT_THROW(RunManifestFromJson(manifest), std::runtime_error);
}

TEST(ColourCapture, RgbFramesAreStoredAsRgbAndLoadBackUnchanged) {
  TempDir dir;
  RunManifest header;
  header.width = 5;
  header.height = 3;
  header.bit_depth = 16;
  header.mosaic = "RGB";
  drivers::Frame frame;
  frame.width = 5;
  frame.height = 3;
  frame.bit_depth = 16;
  frame.pixel_format = "RGB16";
  for (int i = 0; i < 5 * 3 * 3; ++i) frame.pixels.push_back(static_cast<std::uint16_t>(1000 * i + 7));
  const std::string run = (dir.path() / "run").string();
  RunWriter writer(run, header);
  config::CaptureStep step;
  step.label = "0000_dark";
  const FrameRecord record = writer.WriteFrame(step, frame);
  const cv::Mat loaded = LoadFrame(run, record);  // checks the checksum too
  ASSERT_EQ(loaded.type(), CV_16UC3);
  EXPECT_EQ(loaded.at<cv::Vec3w>(0, 1), cv::Vec3w(3007, 4007, 5007));  // R, G, B of pixel 1
}

// Runs `photorig ARGS`, returning its exit code.
int Photorig(const std::string& args) {
  const std::string command = std::string(PHOTORIG_BIN_DIR) + "/photorig " + args + " > /dev/null 2>&1";
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(ColourPhotometricStereo, AlbedoAfterCalibrationIsWithinCiede2000OfTwoAndNormalsAsGoodAsMono) {
  TempDir dir;
  const std::string src = SourceDir();
  // Calibrate the simulated camera on its chart, through the same mosaic.
  ASSERT_EQ(Photorig("calibrate color --sim-camera nikon-5100 --illuminant D65 --rig " + src +
                     "/config/rigs/sim-dome-colour.yaml --bayer RGGB --out " + (dir.path() / "cal").string()),
            0);
  const std::string model = (dir.path() / "cal" / "model.yaml").string();

  RunRequest request;
  request.recipe_path = src + "/config/recipes/ps-colour-sphere.yaml";
  request.output_directory = (dir.path() / "colour").string();
  request.solve = false;
  ASSERT_EQ(ExecuteRun(request).capture.status, CaptureStatus::kComplete);
  const RunManifest manifest = LoadRunManifest(request.output_directory);
  EXPECT_EQ(manifest.mosaic, "RGGB");
  EXPECT_EQ(manifest.pixel_format, "BayerRG12");
  EXPECT_FALSE(manifest.color_model_hash.empty());

  config::PhotometricStereoRequest solve;
  solve.method = solvers::ps::Method::kLambertian;
  solve.integrator = std::nullopt;  // normals only
  ColorStackOptions options;
  options.color_model_path = model;
  const std::string out = (dir.path() / "colour-ps").string();
  const PhotometricStereoResult colour = SolvePhotometricStereoRun(request.output_directory, solve, out, options);
  ASSERT_TRUE(colour.usable()) << colour.summary.message;
  ASSERT_TRUE(colour.albedo_ciede2000_vs_truth);
  const auto& de = *colour.albedo_ciede2000_vs_truth;
  EXPECT_GT(de.interior.pixels, 50000);
  EXPECT_LE(de.interior.mean, 2.0);
  EXPECT_LE(de.interior.p95, 3.0);
  ASSERT_TRUE(colour.color);
  EXPECT_EQ(colour.color->color_space, "linear-srgb");
  EXPECT_EQ(colour.color->demosaic, "bilinear");
  EXPECT_EQ(colour.color->color_model_hash, config::LoadColorModelFile(model).content_hash);

  const cv::Mat albedo = ReadFloatTiff(out + "/albedo.tiff");
  EXPECT_EQ(albedo.type(), CV_32FC3);
  EXPECT_EQ(ReadImage(out + "/albedo.png").type(), CV_8UC3);
  const nlohmann::json report = nlohmann::json::parse(std::ifstream(out + "/report.json"));
  EXPECT_EQ(report.at("color").at("mosaic"), "RGGB");
  EXPECT_EQ(report.at("color").at("color_model").at("hash"), colour.color->color_model_hash);

  // The same scene through the monochrome camera of sim-dome.yaml.
  RunRequest mono_request = request;
  mono_request.rig_path = src + "/config/rigs/sim-dome.yaml";
  mono_request.output_directory = (dir.path() / "mono").string();
  ASSERT_EQ(ExecuteRun(mono_request).capture.status, CaptureStatus::kComplete);
  const PhotometricStereoResult mono =
      SolvePhotometricStereoRun(mono_request.output_directory, solve, (dir.path() / "mono-ps").string());
  ASSERT_TRUE(mono.normals_vs_truth && colour.normals_vs_truth);
  EXPECT_FALSE(mono.color);
  EXPECT_EQ(ReadFloatTiff((dir.path() / "mono-ps" / "albedo.tiff").string()).channels(), 1);
  // The colour camera loses light to its filters and blurs a pixel in
  // demosaicing; on a smooth sphere its normals are as good as the mono ones.
  EXPECT_LE(colour.normals_vs_truth->mean_deg, 1.2 * mono.normals_vs_truth->mean_deg + 0.05);
  EXPECT_LE(colour.normals_vs_truth->mean_deg, 0.5);
}

TEST(ColourModelFile, AMalformedModelIsNamedWithItsFileAndLine) {
  TempDir dir;
  const std::string good = SourceDir() + "/config/color/sim-dome-colour-nikon-5100-d65.yaml";
  EXPECT_NO_THROW(config::LoadColorModelFile(good));
  std::ifstream in(good);
  std::stringstream text;
  text << in.rdbuf();
  // A coefficient row with two numbers, on the model's third row.
  std::string bad = text.str();
  const std::size_t row = bad.find("  - [", bad.find("  - [", bad.find("  - [") + 1) + 1);
  const std::size_t comma = bad.rfind(',', bad.find('\n', row));
  bad.erase(comma, bad.find(']', comma) - comma);
  const std::string path = dir.Write("model.yaml", bad);
  try {
    config::LoadColorModelFile(path);
    FAIL() << "a malformed model loaded";
  } catch (const config::ConfigError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_EQ(e.line(), 4) << e.what();  // coefficients start on line 2
    EXPECT_EQ(e.key(), "coefficients.2");
    EXPECT_NE(std::string(e.what()).find(path + ":4"), std::string::npos) << e.what();
  }
  // Not YAML at all: the parser's position.
  const std::string broken = dir.Write("broken.yaml", "format: photorig-color-model/1\nmodel: [linear\n");
  try {
    config::LoadColorModelFile(broken);
    FAIL() << "broken YAML loaded";
  } catch (const config::ConfigError& e) {
    EXPECT_GT(e.line(), 0) << e.what();
  }
  // A rig naming it fails to load, naming the model file.
  std::string rig_text;
  {
    std::ifstream rig_in(SourceDir() + "/config/rigs/sim-dome-colour.yaml");
    std::stringstream rig_stream;
    rig_stream << rig_in.rdbuf();
    rig_text = rig_stream.str();
  }
  const std::size_t at = rig_text.find("../color/sim-dome-colour-nikon-5100-d65.yaml");
  ASSERT_NE(at, std::string::npos);
  rig_text.replace(at, std::string("../color/sim-dome-colour-nikon-5100-d65.yaml").size(), path);
  const std::string rig = dir.Write("rig.yaml", rig_text);
  try {
    config::LoadRigConfig(rig);
    FAIL() << "a rig with a malformed colour model loaded";
  } catch (const config::ConfigError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_EQ(e.line(), 4);
  }
}

TEST(ColourModelFile, AModelThatIsNotExposureInvariantIsRefusedForPhotometricStereo) {
  TempDir dir;
  const std::string path = dir.Write(
      "affine.json",
      R"({"format": "photorig-color-model/1", "model": "affine", "loss": "xyz", "illuminant": "D65",
 "white_xyz": [0.95, 1, 1.09], "input_scale": 1,
 "coefficients": [[1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 0]]})");
  try {
    config::LoadColorModelFile(path);
    FAIL() << "an affine model loaded";
  } catch (const config::ConfigError& e) {
    EXPECT_EQ(e.key(), "model");
    EXPECT_EQ(e.line(), 1);
  }
}

// A tiny DiLiGenT-layout folder: a Lambertian sphere with an RGB albedo under
// lights of different colours.
TEST(ColourDiligent, AnRgbFolderKeepsItsThreeChannelsWithPerChannelIntensities) {
  TempDir dir;
  constexpr int kSize = 48;
  const std::vector<Eigen::Vector3d> lights = {{0.3, 0.2, 0.93}, {-0.3, 0.25, 0.92}, {0.2, -0.3, 0.93},
                                               {-0.25, -0.3, 0.92}, {0.0, 0.0, 1.0}, {0.4, -0.1, 0.91}};
  const std::vector<Eigen::Vector3d> intensities = {{1.0, 1.0, 1.0}, {1.3, 1.0, 0.7}, {0.8, 1.0, 1.2},
                                                    {1.1, 0.9, 1.0}, {1.0, 1.2, 0.9}, {0.7, 0.8, 1.3}};
  const Eigen::Vector3d albedo(0.7, 0.45, 0.2);
  std::string names, directions, intensity_text;
  cv::Mat mask = cv::Mat::zeros(kSize, kSize, CV_8U);
  for (std::size_t k = 0; k < lights.size(); ++k) {
    const Eigen::Vector3d w = lights[k].normalized();
    cv::Mat image(kSize, kSize, CV_16UC3, cv::Scalar::all(0));
    for (int y = 0; y < kSize; ++y)
      for (int x = 0; x < kSize; ++x) {
        const double nx = (x + 0.5 - kSize / 2.0) / (0.45 * kSize), ny = -(y + 0.5 - kSize / 2.0) / (0.45 * kSize);
        if (nx * nx + ny * ny >= 0.8) continue;
        mask.at<std::uint8_t>(y, x) = 255;
        const Eigen::Vector3d n(nx, ny, std::sqrt(1.0 - nx * nx - ny * ny));
        const double shading = std::max(0.0, n.dot(w)) / M_PI * 60000.0;
        for (int c = 0; c < 3; ++c)  // OpenCV writes B, G, R
          image.at<cv::Vec3w>(y, x)[2 - c] = cv::saturate_cast<std::uint16_t>(albedo[c] * intensities[k][c] * shading);
      }
    char name[16];
    std::snprintf(name, sizeof(name), "%03zu.png", k + 1);
    cv::imwrite((dir.path() / name).string(), image);
    names += std::string(name) + "\n";
    directions += std::to_string(w.x()) + " " + std::to_string(w.y()) + " " + std::to_string(w.z()) + "\n";
    intensity_text += std::to_string(intensities[k][0]) + " " + std::to_string(intensities[k][1]) + " " +
                      std::to_string(intensities[k][2]) + "\n";
  }
  cv::imwrite((dir.path() / "mask.png").string(), mask);
  dir.Write("filenames.txt", names);
  dir.Write("light_directions.txt", directions);
  dir.Write("light_intensities.txt", intensity_text);

  const PhotometricStereoInput input = LoadDiligent(dir.path().string());
  ASSERT_TRUE(input.color);
  EXPECT_EQ(input.color->light_count(), 6);
  EXPECT_EQ(input.color->images.front().type(), CV_32FC3);
  EXPECT_EQ(input.color->provenance.mosaic, "RGB");

  config::PhotometricStereoRequest request;
  request.method = solvers::ps::Method::kLambertian;
  request.integrator = std::nullopt;  // normals only
  const std::string out = (dir.path() / "ps").string();
  const PhotometricStereoResult result = SolveAndWrite(input, request, out);
  ASSERT_TRUE(result.usable()) << result.summary.message;
  const cv::Mat solved_albedo = ReadFloatTiff(out + "/albedo.tiff");
  ASSERT_EQ(solved_albedo.type(), CV_32FC3);
  // In DN per unit intensity: albedo_c x 60000, each channel under its own light colour.
  const cv::Scalar mean = cv::mean(solved_albedo, ReadImage(out + "/mask.png"));
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean[c] / 60000.0, albedo[c], 0.01 * albedo[c]) << "channel " << c;
  const nlohmann::json report = nlohmann::json::parse(std::ifstream(out + "/report.json"));
  EXPECT_EQ(report.at("color").at("color_space"), "camera-rgb");
}

}  // namespace
}  // namespace photorig::daemon
