// The chart's fixed position in the rig YAML, the chart rendered where the rig
// says, a Bayer raw demosaiced before measuring, and the one-command
// calibration on the simulated dome.

#include "../daemon/test_support.h"
#include "photorig/solvers/color/apply.h"
#include "photorig/solvers/color/calibration.h"
#include "photorig/daemon/io/image_io.h"
#include "photorig/config/rig.h"
#include "photorig/config/sim.h"
#include "photorig/config/yaml_node.h"
#include "sim_chart.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <regex>

namespace photorig::solvers::color {
namespace {

using photorig::testing::TempDir;

// Demosaic that must succeed.
cv::Mat Demosaiced(const cv::Mat& raw, const std::string& pattern) {
  cv::Mat bgr;
  const solvers::core::Summary summary = Demosaic(raw, pattern, &bgr);
  EXPECT_EQ(summary.termination, solvers::core::Termination::kSuccess) << summary.message;
  return bgr;
}

const std::string kSimDome = photorig::testing::SourceDir() + "/config/rigs/sim-dome.yaml";

std::string SimDomeWithChart(const std::string& chart) {
  const std::string text = photorig::testing::ReadText(kSimDome);
  return std::regex_replace(text, std::regex("color_chart: \\{[^\n]*\\}"), "color_chart: " + chart);
}

// The ConfigError text of loading `chart` in place of the dome's color_chart.
std::string ChartError(const std::string& chart, int* line) {
  TempDir dir;
  const std::string path = dir.Write("rig.yaml", SimDomeWithChart(chart));
  try {
    config::LoadRigConfig(path);
  } catch (const config::ConfigError& e) {
    *line = e.line();
    return e.what();
  }
  return "";
}

std::array<cv::Point2f, 4> ToPoints(const config::ColorChartPlacement& chart) {
  std::array<cv::Point2f, 4> corners;
  for (std::size_t i = 0; i < 4; ++i)
    corners[i] = cv::Point2f(static_cast<float>(chart.corners_px[i].x()), static_cast<float>(chart.corners_px[i].y()));
  return corners;
}

TEST(RigChart, SimDomeNamesTheChartBox) {
  const config::RigConfig rig = config::LoadRigConfig(kSimDome);
  ASSERT_TRUE(rig.camera.color_chart);
  const auto& c = rig.camera.color_chart->corners_px;
  EXPECT_EQ(c[0], Eigen::Vector2d(24, 80));
  EXPECT_EQ(c[2], Eigen::Vector2d(360, 304));
}

TEST(RigChart, CornersAreReadInOrder) {
  TempDir dir;
  const std::string path =
      dir.Write("rig.yaml", SimDomeWithChart("{corners_px: [[30, 90], [350, 84], [356, 300], [26, 306]]}"));
  const config::RigConfig rig = config::LoadRigConfig(path);
  ASSERT_TRUE(rig.camera.color_chart);
  EXPECT_EQ(rig.camera.color_chart->corners_px[1], Eigen::Vector2d(350, 84));
  EXPECT_EQ(rig.camera.color_chart->corners_px[3], Eigen::Vector2d(26, 306));
}

TEST(RigChart, BadPositionsNameFileLineAndKey) {
  const int chart_line = [] {
    const std::string text = SimDomeWithChart("{box_px: [1, 2, 3, 4]}");
    return static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(text.find("color_chart")), '\n')) + 1;
  }();
  int line = 0;
  std::string error = ChartError("{box_px: [24, 80, 336]}", &line);
  EXPECT_NE(error.find("rig.yaml:" + std::to_string(chart_line) + ":"), std::string::npos) << error;
  EXPECT_NE(error.find("camera.color_chart.box_px"), std::string::npos) << error;
  EXPECT_NE(error.find("expected [x, y, w, h]"), std::string::npos) << error;
  EXPECT_EQ(line, chart_line);

  error = ChartError("{box_px: [24, 80, 336, 0]}", &line);
  EXPECT_NE(error.find("width and height must be > 0"), std::string::npos) << error;
  error = ChartError("{box_px: [200, 80, 336, 224]}", &line);
  EXPECT_NE(error.find("outside the 384 x 384 frame"), std::string::npos) << error;
  EXPECT_EQ(line, chart_line);
  error = ChartError("{box_px: [24, 80, 336, 224], corners_px: []}", &line);
  EXPECT_NE(error.find("exactly one of"), std::string::npos) << error;
  error = ChartError("{box: [24, 80, 336, 224]}", &line);
  EXPECT_NE(error.find("box"), std::string::npos) << error;
  // Counter-clockwise corners would put patch 1 in the wrong place.
  error = ChartError("{corners_px: [[30, 90], [26, 306], [356, 300], [350, 84]]}", &line);
  EXPECT_NE(error.find("clockwise"), std::string::npos) << error;
  error = ChartError("{corners_px: [[30, 90], [350, 84], [356]]}", &line);
  EXPECT_NE(error.find("camera.color_chart.corners_px"), std::string::npos) << error;
  error = ChartError("{corners_px: [[30, 90], [350, 84], [356, x], [26, 306]]}", &line);
  EXPECT_NE(error.find("corners_px[2]"), std::string::npos) << error;
}

TEST(RigChart, PositionOutsideTheImageIsRefusedByName) {
  const cv::Mat image(200, 300, CV_16UC3, cv::Scalar::all(1000));
  LocateOptions options;
  options.use_detector = false;
  options.fixed_corners = ParseChartCorners("100,20,240,160");
  options.fixed_source = "rig.yaml camera.color_chart";
  const LocateResult result = LocateChart(image, options);
  EXPECT_FALSE(result.location);
  EXPECT_NE(result.message.find("rig.yaml camera.color_chart has a corner at (340, 20), outside the 300 x 200 image"),
            std::string::npos)
      << result.message;
}

TEST(RigChart, ChartRenderedWhereTheRigSaysCalibratesFromThatPosition) {
  const config::RigConfig rig = config::LoadRigConfig(kSimDome);
  const sim::ChartGeometry geometry =
      sim::ChartGeometry::PlacedIn(cv::Rect2d(24, 80, 336, 224), cv::Size(rig.camera.width, rig.camera.height));
  const std::array<cv::Point2f, 4> truth = geometry.GridCorners();
  const std::array<cv::Point2f, 4> from_rig = ToPoints(*rig.camera.color_chart);
  for (std::size_t i = 0; i < 4; ++i) EXPECT_LE(cv::norm(truth[i] - from_rig[i]), 1.0) << "corner " << i;

  const sim::SensorModel& sensor = rig.sim->sensor;
  const sim::ChartRender render = sim::RenderColorChart(testing::SimSpectra("nikon-5100", Illuminant::kD65), geometry,
                                                        sensor, sim::ExposureForWhite(sensor, 0.8), 0.0, 11);
  ASSERT_EQ(render.raw.size(), cv::Size(384, 384));
  LocateOptions locate;
  locate.use_detector = false;
  locate.fixed_corners = from_rig;
  const ChartCalibration result = CalibrateChartImage(render.raw, render.dark, Illuminant::kD65, locate,
                                                      testing::SimMeasureOptions(render), CalibrationOptions{});
  ASSERT_TRUE(result.summary.IsSolutionUsable()) << result.summary.message;
  EXPECT_EQ(result.located.location->method, "fixed-roi");
  EXPECT_LE(result.summary.models[static_cast<std::size_t>(result.summary.chosen)].held_out_mean, 0.8);

  EXPECT_THROW(sim::ChartGeometry::PlacedIn(cv::Rect2d(24, 80, 336, 150), cv::Size(384, 384)), std::invalid_argument);
  EXPECT_THROW(sim::ChartGeometry::PlacedIn(cv::Rect2d(60, 80, 336, 224), cv::Size(384, 384)), std::invalid_argument);
}

TEST(Bayer, PatchMeansAfterDemosaicMatchTheRgbRender) {
  const sim::ChartGeometry geometry;
  const sim::ChartRender render = testing::RenderChart("nikon-5100", Illuminant::kD65);
  const ChartLocation location{geometry.GridCorners(), "fixed-roi"};
  const MeasureOptions options = testing::SimMeasureOptions(render);
  const auto rgb = testing::Measured(render.raw, render.dark, location, options);
  for (const std::string pattern : {"RGGB", "GBRG"}) {
    const cv::Mat raw = Demosaiced(sim::BayerMosaic(render.raw, pattern), pattern);
    const cv::Mat dark = Demosaiced(sim::BayerMosaic(render.dark, pattern), pattern);
    ASSERT_EQ(raw.type(), CV_16UC3);
    const auto demosaiced = testing::Measured(raw, dark, location, options);
    for (int p = 0; p < kChartPatches; ++p) {
      const PatchMeasurement& a = demosaiced[static_cast<std::size_t>(p)];
      const PatchMeasurement& b = rgb[static_cast<std::size_t>(p)];
      ASSERT_EQ(a.flag, PatchFlag::kOk) << pattern << " patch " << p + 1;
      for (int c = 0; c < 3; ++c) {
        // A red or blue site is one pixel in four: its mean has twice the standard error of a full channel.
        const double tolerance = 4.0 * 2.0 * b.stddev[c] / std::sqrt(b.pixels) + 1.0;
        EXPECT_NEAR(a.rgb[c], b.rgb[c], tolerance) << pattern << " patch " << p + 1 << " channel " << c;
      }
    }
  }
  // A mosaic read as if its filters were the other way round swaps red and blue.
  const cv::Mat swapped = Demosaiced(sim::BayerMosaic(render.raw, "RGGB"), "BGGR");
  const auto wrong = testing::Measured(swapped, cv::Mat(), location, options);
  EXPECT_NEAR(wrong[14].rgb.z(), rgb[14].rgb.x() + sim::SensorModel{}.black_level_dn, 0.1 * rgb[14].rgb.x());  // red patch
  cv::Mat untouched;
  EXPECT_EQ(Demosaic(render.raw, "RGGB", &untouched).termination, solvers::core::Termination::kInvalidInput);
  const solvers::core::Summary unknown = Demosaic(sim::BayerMosaic(render.raw, "RGGB"), "RGBG", &untouched);
  EXPECT_EQ(unknown.termination, solvers::core::Termination::kInvalidOptions);
  EXPECT_NE(unknown.message.find("'RGBG'"), std::string::npos) << unknown.message;
  EXPECT_TRUE(untouched.empty());
  EXPECT_THROW(sim::BayerMosaic(render.raw, "XYZW"), std::invalid_argument);
}

TEST(CalibrateColorCommand, SimulatedDomeOneCommandUsesTheRigPosition) {
  TempDir dir;
  const auto out = dir.path() / "cal";
  ASSERT_EQ(photorig::testing::RunPhotorig("calibrate color --sim-camera nikon-5100 --rig " + kSimDome +
                                               " --no-detect --bayer RGGB --models linear,root-poly-2 --out " +
                                               out.string(),
                                           dir.path() / "log"),
            0)
      << photorig::testing::ReadText(dir.path() / "log");
  const nlohmann::json report = nlohmann::json::parse(photorig::testing::ReadText(out / "report.json"));
  EXPECT_EQ(report["chart_location_method"], "fixed-roi");
  EXPECT_NE(report["chart_location"].get<std::string>().find("camera.color_chart"), std::string::npos);
  EXPECT_EQ(report["bayer"], "RGGB");
  EXPECT_TRUE(std::filesystem::exists(out / "model.yaml"));
  EXPECT_EQ(daemon::ReadImage((out / "chart.png").string()).channels(), 1);

  // The model applied to the same Bayer raw gives the white patch its reference luminance.
  ASSERT_EQ(photorig::testing::RunPhotorig("apply-color --model " + (out / "model.yaml").string() + " --in " +
                                               (out / "chart.png").string() + " --dark " + (out / "dark.png").string() +
                                               " --bayer RGGB --out " + (dir.path() / "applied").string(),
                                           dir.path() / "log3"),
            0)
      << photorig::testing::ReadText(dir.path() / "log3");
  const cv::Mat xyz = daemon::ReadFloatTiff((dir.path() / "applied" / "chart_xyz.tiff").string());
  const cv::Point2f white = ChartLocation{ToPoints(*config::LoadRigConfig(kSimDome).camera.color_chart), ""}.PatchCentre(kWhitePatch);
  const ChartReference reference = ColorCheckerReference(Illuminant::kD65, ReferenceGrid());
  EXPECT_NEAR(xyz.at<cv::Vec3f>(cv::Point(white))[1], reference.xyz[kWhitePatch].y(), 0.03);

  // The flag overrides the rig: a box outside the frame is refused, naming the flag.
  EXPECT_EQ(photorig::testing::RunPhotorig("calibrate color --image " + (out / "chart.png").string() +
                                               " --bayer RGGB --no-detect --rig " + kSimDome +
                                               " --chart-roi 100,100,400,200 --out " + (dir.path() / "x").string(),
                                           dir.path() / "log2"),
            1);  // no usable model: a failed solve (docs/cli.md)
  EXPECT_NE(photorig::testing::ReadText(dir.path() / "log2").find("--chart-roi 100,100,400,200 has a corner"),
            std::string::npos)
      << photorig::testing::ReadText(dir.path() / "log2");
}

TEST(CalibrateColorCommand, BadChartRoiAndUnknownCameraAreUsageErrors) {
  TempDir dir;
  EXPECT_EQ(photorig::testing::RunPhotorig("calibrate color --sim-camera nikon-5100 --no-detect --chart-roi 1,2,3 --out " +
                                               (dir.path() / "x").string(),
                                           dir.path() / "log"),
            2);
  const std::string roi = photorig::testing::ReadText(dir.path() / "log");
  EXPECT_NE(roi.find("--chart-roi 1,2,3: 3 numbers, not 4 (x,y,w,h) or 8"), std::string::npos) << roi;
  EXPECT_NE(roi.find("give the chart's outer corners in image pixels"), std::string::npos) << roi;

  EXPECT_EQ(photorig::testing::RunPhotorig("calibrate color --sim-camera nikon-9999 --out " + (dir.path() / "y").string(),
                                           dir.path() / "log2"),
            2);
  const std::string camera = photorig::testing::ReadText(dir.path() / "log2");
  EXPECT_NE(camera.find("unknown camera 'nikon-9999' (known: nikon-5100, sigma-sdmerill, canon-5d-mark-ii)"),
            std::string::npos)
      << camera;
}

}  // namespace
}  // namespace photorig::solvers::color
