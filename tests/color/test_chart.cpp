#include "photorig/solvers/color/chart.h"
#include "sim_chart.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <string>

namespace photorig::solvers::color {
namespace {

using testing::RenderChart;
using testing::SimMeasureOptions;

double CornerError(const ChartLocation& location, const sim::ChartGeometry& geometry) {
  double worst = 0.0;
  for (int p = 0; p < kChartPatches; ++p) {
    const cv::Rect rect = geometry.PatchRect(p);
    const cv::Point2f truth(rect.x + 0.5f * rect.width, rect.y + 0.5f * rect.height);
    const cv::Point2f found = location.PatchCentre(p);
    worst = std::max(worst, static_cast<double>(std::hypot(found.x - truth.x, found.y - truth.y)));
  }
  return worst;
}

TEST(ChartLocate, DetectorFindsTheSimulatedChartInPatchOrder) {
  const sim::ChartGeometry geometry;
  const sim::ChartRender render = RenderChart("nikon-5100", Illuminant::kD65);
  const LocateResult result = LocateChart(render.raw, LocateOptions{});
  ASSERT_TRUE(result.location) << result.message;
  EXPECT_EQ(result.location->method, "detector");
  // Patch centres within a fifth of a patch of the truth, in the right order.
  EXPECT_LT(CornerError(*result.location, geometry), 0.2 * geometry.patch_px);
}

TEST(ChartLocate, FindsARotatedChart) {
  const sim::ChartGeometry geometry;
  const sim::ChartRender render = RenderChart("nikon-5100", Illuminant::kD65);
  cv::Mat rotated;
  cv::rotate(render.raw, rotated, cv::ROTATE_180);
  const LocateResult result = LocateChart(rotated, LocateOptions{});
  ASSERT_TRUE(result.location) << result.message;
  // Patch 1 (dark skin) is now at the bottom right.
  const cv::Rect first = geometry.PatchRect(0);
  const cv::Point2f centre = result.location->PatchCentre(0);
  EXPECT_NEAR(centre.x, render.raw.cols - (first.x + 0.5 * first.width), 0.2 * geometry.patch_px);
  EXPECT_NEAR(centre.y, render.raw.rows - (first.y + 0.5 * first.height), 0.2 * geometry.patch_px);
}

TEST(ChartLocate, FallsBackToTheFixedPositionWhenNothingIsDetected) {
  const cv::Mat blank(200, 300, CV_16UC3, cv::Scalar::all(1000));
  LocateOptions options;
  const LocateResult nothing = LocateChart(blank, options);
  EXPECT_FALSE(nothing.location);
  EXPECT_EQ(nothing.termination, core::Termination::kFailure);
  EXPECT_NE(nothing.message.find("no fixed chart position"), std::string::npos);
  options.fixed_corners = ParseChartCorners("10,20,240,160");
  const LocateResult result = LocateChart(blank, options);
  ASSERT_TRUE(result.location);
  EXPECT_EQ(result.termination, core::Termination::kSuccess);
  EXPECT_EQ(result.location->method, "fixed-roi");
  EXPECT_FLOAT_EQ(result.location->PatchCentre(0).x, 10.0f + 20.0f);
  EXPECT_FLOAT_EQ(result.location->PatchCentre(0).y, 20.0f + 20.0f);
}

TEST(ChartLocate, FixedCornersRoundNoConvexQuadrilateralAreRefused) {
  const cv::Mat blank(200, 300, CV_16UC3, cv::Scalar::all(1000));
  LocateOptions options;
  options.use_detector = false;
  options.fixed_source = "--chart-roi test";
  // Top-left, bottom-right, top-right, bottom-left: two edges cross.
  options.fixed_corners = std::array<cv::Point2f, 4>{{{10, 20}, {250, 180}, {250, 20}, {10, 180}}};
  std::string why;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("fixed_corners (--chart-roi test)"), std::string::npos) << why;
  const LocateResult result = LocateChart(blank, options);
  EXPECT_EQ(result.termination, core::Termination::kInvalidOptions);
  EXPECT_FALSE(result.location);
  EXPECT_NE(result.message.find("fixed_corners"), std::string::npos) << result.message;
  // Three corners in line; a corner that is no number.
  options.fixed_corners = std::array<cv::Point2f, 4>{{{10, 20}, {130, 20}, {250, 20}, {10, 180}}};
  EXPECT_FALSE(options.IsValid(nullptr));
  options.fixed_corners = std::array<cv::Point2f, 4>{{{10, 20}, {250, 20}, {250, NAN}, {10, 180}}};
  EXPECT_FALSE(options.IsValid(nullptr));
  // Either way round is a chart: a mirrored view lists its corners anticlockwise.
  options.fixed_corners = std::array<cv::Point2f, 4>{{{250, 20}, {10, 20}, {10, 180}, {250, 180}}};
  EXPECT_TRUE(options.IsValid(&why)) << why;
}

TEST(ChartLocate, ChartPositionTextIsChecked) {
  const auto refused = [](const std::string& text, const std::string& reason) {
    std::string why;
    EXPECT_FALSE(ParseChartCorners(text, &why)) << text;
    EXPECT_NE(why.find(reason), std::string::npos) << text << ": " << why;
  };
  refused("1,2,3", "3 numbers, not 4 (x,y,w,h) or 8");
  refused("1,2,x,4", "'x' is not a number");
  refused("1,2,3.5px,4", "'3.5px' is not a number");
  refused("1,2,,4", "'' is not a number");
  refused("1,2,1e99,4", "'1e99' is not a number");
  refused("1,2,-3,4", "width and height must be > 0");
  const auto corners = ParseChartCorners("0,0,10,0,10,5,0,5");
  ASSERT_TRUE(corners);
  EXPECT_EQ((*corners)[2], cv::Point2f(10, 5));
  // Blanks after the commas, as people type them.
  const auto box = ParseChartCorners("10, 20, 240, 160");
  ASSERT_TRUE(box);
  EXPECT_EQ((*box)[2], cv::Point2f(250, 180));
}

TEST(ChartMeasure, TrimmedMeansMatchTheNoiseFreeSignal) {
  const sim::ChartGeometry geometry;
  const sim::ChartRender render = RenderChart("nikon-5100", Illuminant::kD65);
  const ChartLocation location{geometry.GridCorners(), "fixed-roi"};
  const std::vector<PatchMeasurement> patches = testing::Measured(render.raw, render.dark, location, SimMeasureOptions(render));
  const sim::SensorModel sensor;
  const double dn_per_signal = sensor.DnPerRadiance(sim::ExposureForWhite(sensor, 0.8), 0.0);
  for (int p = 0; p < kChartPatches; ++p) {
    const PatchMeasurement& m = patches[static_cast<std::size_t>(p)];
    ASSERT_EQ(m.flag, PatchFlag::kOk) << "patch " << p + 1;
    EXPECT_GE(m.pixels, 100);
    const cv::Rect rect = geometry.PatchRect(p);
    const cv::Vec3f truth = render.signal.at<cv::Vec3f>(rect.y + rect.height / 2, rect.x + rect.width / 2);
    for (int c = 0; c < 3; ++c) {
      const double expected = truth[c] * dn_per_signal;
      // Within 4 standard errors plus the dark frame's own noise.
      EXPECT_NEAR(m.rgb[c], expected, 4.0 * m.stddev[c] / std::sqrt(m.pixels) + 1.0) << "patch " << p + 1 << " c " << c;
    }
  }
}

TEST(ChartMeasure, WithoutDarkSubtractionTheBlackLevelBiasesTheMeans) {
  const sim::ChartGeometry geometry;
  const sim::ChartRender render = RenderChart("nikon-5100", Illuminant::kD65);
  const ChartLocation location{geometry.GridCorners(), "fixed-roi"};
  MeasureOptions options = SimMeasureOptions(render);
  const auto with_dark = testing::Measured(render.raw, render.dark, location, options);
  const auto raw = testing::Measured(render.raw, cv::Mat(), location, options);
  options.black_level = sim::SensorModel{}.black_level_dn;
  const auto with_black = testing::Measured(render.raw, cv::Mat(), location, options);
  EXPECT_NEAR(raw[23].rgb.y() - with_dark[23].rgb.y(), 64.0, 1.0);
  EXPECT_NEAR(with_black[23].rgb.y(), with_dark[23].rgb.y(), 1.0);
}

TEST(ChartMeasure, FlagsSaturatedUnderexposedAndOutOfFramePatches) {
  const sim::ChartGeometry geometry;
  const ChartLocation location{geometry.GridCorners(), "fixed-roi"};
  // Over-exposed 2x: the white and light patches clip.
  const sim::ChartRender bright = RenderChart("nikon-5100", Illuminant::kD65, 1.6);
  const auto over = testing::Measured(bright.raw, bright.dark, location, SimMeasureOptions(bright));
  EXPECT_EQ(over[kWhitePatch].flag, PatchFlag::kSaturated);
  EXPECT_EQ(over[23].flag, PatchFlag::kOk);  // black stays fine
  // Under-exposed 1000x: the dark patches sink into the read noise.
  const sim::ChartRender dim = RenderChart("nikon-5100", Illuminant::kD65, 0.0008);
  const auto under = testing::Measured(dim.raw, dim.dark, location, SimMeasureOptions(dim));
  EXPECT_EQ(under[23].flag, PatchFlag::kUnderexposed);
  // A chart half out of frame.
  ChartLocation shifted = location;
  for (auto& corner : shifted.corners) corner.x += 0.6f * static_cast<float>(geometry.width());
  const auto missing = testing::Measured(bright.raw, bright.dark, shifted, SimMeasureOptions(bright));
  EXPECT_EQ(missing[5].flag, PatchFlag::kTooFewPixels);
  // Mismatched dark frame.
  std::vector<PatchMeasurement> untouched;
  const solvers::core::Summary mismatched =
      MeasurePatches(bright.raw, cv::Mat(10, 10, CV_16UC3), location, SimMeasureOptions(bright), &untouched);
  EXPECT_EQ(mismatched.termination, solvers::core::Termination::kInvalidInput);
  EXPECT_NE(mismatched.message.find("dark frame"), std::string::npos) << mismatched.message;
  EXPECT_TRUE(untouched.empty());
}

}  // namespace
}  // namespace photorig::solvers::color
