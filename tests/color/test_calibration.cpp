#include "photorig/solvers/color/apply.h"
#include "photorig/solvers/color/calibration.h"
#include "photorig/solvers/color/colorimetry.h"
#include "sim_chart.h"

#include <gtest/gtest.h>

#include <cmath>

namespace photorig::solvers::color {
namespace {

using testing::RenderChart;
using testing::SimMeasureOptions;

// CameraToXyz that must succeed.
cv::Mat ToXyz(const ColorModel& model, const cv::Mat& image, const cv::Mat& dark, const ApplyOptions& options) {
  cv::Mat xyz;
  const solvers::core::Summary summary = CameraToXyz(model, image, dark, options, &xyz);
  EXPECT_EQ(summary.termination, solvers::core::Termination::kSuccess) << summary.message;
  return xyz;
}

LocateOptions FixedChart() {
  LocateOptions options;
  options.use_detector = false;
  options.fixed_corners = sim::ChartGeometry{}.GridCorners();
  return options;
}

const ModelEvaluation& Find(const CalibrationSummary& summary, const std::string& name) {
  for (const auto& m : summary.models)
    if (m.spec.Name() == name) return m;
  throw std::logic_error("no model " + name);
}

TEST(ColorCalibration, ChosenModelMeetsTheAccuracyTargetForNikonUnderD65) {
  const sim::ChartRender render = RenderChart("nikon-5100", Illuminant::kD65);
  const ChartCalibration result = CalibrateChartImage(render.raw, render.dark, Illuminant::kD65, FixedChart(),
                                                      SimMeasureOptions(render), CalibrationOptions{});
  ASSERT_TRUE(result.summary.IsSolutionUsable()) << result.summary.message;
  const ModelEvaluation& chosen = result.summary.models[static_cast<std::size_t>(result.summary.chosen)];
  EXPECT_LE(chosen.held_out_mean, 0.8) << result.summary.message;
  // Every model fits its training patches at least as well as it predicts held-out ones,
  // and the richest model overfits: its held-out error exceeds the chosen one's.
  for (const auto& m : result.summary.models) {
    ASSERT_TRUE(m.usable) << m.spec.Name() << ": " << m.note;
    EXPECT_LE(m.training_mean, m.held_out_mean + 1e-9) << m.spec.Name();
  }
  EXPECT_LT(Find(result.summary, "root-poly-3").training_mean, Find(result.summary, "linear").training_mean);
  EXPECT_GT(Find(result.summary, "poly-3").held_out_mean, chosen.held_out_mean);
}

TEST(ColorCalibration, Ciede2000LossLowersTheTrainingError) {
  const sim::ChartRender render = RenderChart("nikon-5100", Illuminant::kD65);
  CalibrationOptions options;
  options.candidates = {*ModelSpec::Parse("linear")};
  const auto xyz = CalibrateChartImage(render.raw, render.dark, Illuminant::kD65, FixedChart(), SimMeasureOptions(render), options);
  options.loss = FitLoss::kCiede2000;
  const auto de = CalibrateChartImage(render.raw, render.dark, Illuminant::kD65, FixedChart(), SimMeasureOptions(render), options);
  ASSERT_TRUE(xyz.summary.IsSolutionUsable() && de.summary.IsSolutionUsable());
  EXPECT_LT(de.summary.models[0].training_mean, xyz.summary.models[0].training_mean - 0.05);
}

TEST(ColorCalibration, RootPolynomialIsExposureInvariantAndPolynomialIsNot) {
  const sim::ChartRender render = RenderChart("canon-5d-mark-ii", Illuminant::kD65);
  const ChartCalibration result = CalibrateChartImage(render.raw, render.dark, Illuminant::kD65, FixedChart(),
                                                      SimMeasureOptions(render), CalibrationOptions{});
  ASSERT_TRUE(result.summary.IsSolutionUsable());
  const Eigen::Vector3d rgb = result.patches[12].rgb;  // blue
  for (const char* name : {"linear", "root-poly-2", "root-poly-3"}) {
    const ColorModel& m = Find(result.summary, name).model;
    EXPECT_LT((m.ToXyz(0.5 * rgb) - 0.5 * m.ToXyz(rgb)).norm(), 1e-9 * m.ToXyz(rgb).norm() + 1e-12) << name;
  }
  const ColorModel& poly = Find(result.summary, "poly-2").model;
  EXPECT_GT((poly.ToXyz(0.5 * rgb) - 0.5 * poly.ToXyz(rgb)).norm(), 1e-3 * poly.ToXyz(rgb).norm());
}

TEST(ColorCalibration, OnlyGreyPatchesIsIllConditionedAndRefused) {
  const sim::ChartRender render = RenderChart("nikon-5100", Illuminant::kD65);
  const ChartCalibration full = CalibrateChartImage(render.raw, render.dark, Illuminant::kD65, FixedChart(),
                                                    SimMeasureOptions(render), CalibrationOptions{});
  CalibrationInput input;
  input.reference_xyz = full.reference.xyz;
  input.white_xyz = full.reference.white_xyz;
  // The grey ramp twice (a chart of neutrals): six distinct colours, all on one line.
  for (int p = 0; p < 24; ++p) {
    input.camera_rgb.push_back(full.patches[static_cast<std::size_t>(p)].rgb);
    input.usable.push_back(p >= 18);
  }
  for (int p = 18; p < 24; ++p) {
    input.camera_rgb.push_back(full.patches[static_cast<std::size_t>(p)].rgb * 1.01);
    input.reference_xyz.push_back(full.reference.xyz[static_cast<std::size_t>(p)] * 1.01);
    input.usable.push_back(true);
  }
  CalibrationOptions options;
  options.candidates = {*ModelSpec::Parse("linear"), *ModelSpec::Parse("root-poly-2")};
  const CalibrationSummary summary = Calibrate(input, options);
  EXPECT_FALSE(summary.IsSolutionUsable());
  EXPECT_NE(summary.message.find("near-singular"), std::string::npos) << summary.message;
}

TEST(ColorCalibration, MissingPatchesLeaveOutModelsTheyCannotSupport) {
  const sim::ChartRender render = RenderChart("nikon-5100", Illuminant::kD65);
  const ChartCalibration full = CalibrateChartImage(render.raw, render.dark, Illuminant::kD65, FixedChart(),
                                                    SimMeasureOptions(render), CalibrationOptions{});
  CalibrationInput input;
  input.reference_xyz = full.reference.xyz;
  input.white_xyz = full.reference.white_xyz;
  for (int p = 0; p < 24; ++p) {
    input.camera_rgb.push_back(full.patches[static_cast<std::size_t>(p)].rgb);
    input.usable.push_back(p < 12 || p == kWhitePatch);  // 13 patches: a torn chart
  }
  const CalibrationSummary summary = Calibrate(input, CalibrationOptions{});
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  EXPECT_EQ(summary.patches_used, 13);
  EXPECT_FALSE(Find(summary, "poly-3").usable);
  EXPECT_NE(Find(summary, "poly-3").note.find("usable patches"), std::string::npos);
  EXPECT_TRUE(std::isnan(Find(summary, "linear").held_out_de[20]));  // not measured, not scored

  for (int p = 0; p < 24; ++p) input.usable[static_cast<std::size_t>(p)] = p < 3;
  const CalibrationSummary none = Calibrate(input, CalibrationOptions{});
  EXPECT_FALSE(none.IsSolutionUsable());
  EXPECT_NE(none.message.find("only 3 usable patches"), std::string::npos);

  input.usable.pop_back();
  EXPECT_NE(Calibrate(input, CalibrationOptions{}).message.find("one entry per patch"), std::string::npos);
}

TEST(ColorCalibration, SaturatedWhiteFallsBackToAGreyForExposure) {
  const sim::ChartRender render = RenderChart("nikon-5100", Illuminant::kD65, 1.3);
  const ChartCalibration result = CalibrateChartImage(render.raw, render.dark, Illuminant::kD65, FixedChart(),
                                                      SimMeasureOptions(render), CalibrationOptions{});
  EXPECT_EQ(result.patches[kWhitePatch].flag, PatchFlag::kSaturated);
  ASSERT_TRUE(result.summary.IsSolutionUsable()) << result.summary.message;
  EXPECT_GT(result.summary.exposure_patch, kWhitePatch);
  EXPECT_NE(result.summary.message.find("flagged and left out"), std::string::npos);
}

// A white patch the chart does not have is refused, not fallen back from.
TEST(ColorCalibration, AWhitePatchTheChartDoesNotHaveIsRefused) {
  const sim::ChartRender render = RenderChart("nikon-5100", Illuminant::kD65, 0.8);
  CalibrationOptions options;
  options.white_patch = 99;
  const ChartCalibration result = CalibrateChartImage(render.raw, render.dark, Illuminant::kD65, FixedChart(),
                                                      SimMeasureOptions(render), options);
  EXPECT_EQ(result.summary.termination, solvers::core::Termination::kInvalidOptions);
  EXPECT_NE(result.summary.message.find("white_patch 99 is not one of the chart's 24 patches"), std::string::npos)
      << result.summary.message;
}

TEST(ColorCalibration, NoChartGivesAClearFailure) {
  const cv::Mat blank(200, 300, CV_16UC3, cv::Scalar::all(1000));
  const ChartCalibration result =
      CalibrateChartImage(blank, cv::Mat(), Illuminant::kD65, LocateOptions{}, MeasureOptions{}, CalibrationOptions{});
  EXPECT_FALSE(result.summary.IsSolutionUsable());
  EXPECT_NE(result.summary.message.find("no 24-patch chart"), std::string::npos);
}

TEST(ColorApply, CorrectedChartImageReproducesTheReferenceColours) {
  const sim::ChartGeometry geometry;
  const sim::ChartRender render = RenderChart("sigma-sdmerill", Illuminant::kD65);
  const ChartCalibration result = CalibrateChartImage(render.raw, render.dark, Illuminant::kD65, FixedChart(),
                                                      SimMeasureOptions(render), CalibrationOptions{});
  ASSERT_TRUE(result.summary.IsSolutionUsable());
  const ColorModel& model = result.summary.chosen_model();
  const cv::Mat xyz = ToXyz(model, render.raw, render.dark, ApplyOptions{});
  double sum = 0.0;
  for (int p = 0; p < kChartPatches; ++p) {
    const cv::Rect rect = geometry.PatchRect(p);
    const cv::Scalar mean = cv::mean(xyz(rect));
    const Eigen::Vector3d lab = XyzToLab({mean[0], mean[1], mean[2]}, result.reference.white_xyz);
    sum += Ciede2000(lab, XyzToLab(result.reference.xyz[static_cast<std::size_t>(p)], result.reference.white_xyz));
  }
  const ModelEvaluation& chosen = result.summary.models[static_cast<std::size_t>(result.summary.chosen)];
  EXPECT_NEAR(sum / kChartPatches, chosen.training_mean, 0.15);

  // Twice the exposure, told so: the same colours.
  cv::Mat raw, dark;
  render.raw.convertTo(raw, CV_32FC3);
  render.dark.convertTo(dark, CV_32FC3);
  const cv::Mat doubled = ToXyz(model, (raw - dark) * 2.0, cv::Mat(), ApplyOptions{0.0, 2.0});
  EXPECT_NEAR(cv::mean(doubled(geometry.PatchRect(7)))[1], cv::mean(xyz(geometry.PatchRect(7)))[1], 2e-3);

  // sRGB view: the white patch is near-white, the black patch near-black.
  cv::Mat srgb;
  ASSERT_TRUE(XyzToSrgb8(xyz, model.white_xyz, &srgb).IsSolutionUsable());
  const cv::Scalar white = cv::mean(srgb(geometry.PatchRect(kWhitePatch)));
  const cv::Scalar black = cv::mean(srgb(geometry.PatchRect(23)));
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(white[c], 243.0, 6.0);
    EXPECT_NEAR(black[c], 52.0, 6.0);
  }
  // Bad input and bad options end in the summary, naming what is wrong, and leave the output alone.
  cv::Mat untouched;
  const solvers::core::Summary one_channel = CameraToXyz(model, cv::Mat(4, 4, CV_32F), cv::Mat(), ApplyOptions{}, &untouched);
  EXPECT_EQ(one_channel.termination, solvers::core::Termination::kInvalidInput);
  EXPECT_NE(one_channel.message.find("3-channel"), std::string::npos) << one_channel.message;
  const solvers::core::Summary no_exposure = CameraToXyz(model, xyz, cv::Mat(), ApplyOptions{0.0, 0.0}, &untouched);
  EXPECT_EQ(no_exposure.termination, solvers::core::Termination::kInvalidOptions);
  EXPECT_NE(no_exposure.message.find("exposure_ratio"), std::string::npos) << no_exposure.message;
  EXPECT_EQ(XyzToSrgb8(srgb, model.white_xyz, &untouched).termination, solvers::core::Termination::kInvalidInput);
  EXPECT_TRUE(untouched.empty());
}

TEST(ColorApply, EveryModelAgreesPixelByPixelWithItsDoublePrecisionDefinition) {
  const sim::ChartRender render = RenderChart("nikon-5100", Illuminant::kD65);
  const ChartCalibration result = CalibrateChartImage(render.raw, render.dark, Illuminant::kD65, FixedChart(),
                                                      SimMeasureOptions(render), CalibrationOptions{});
  // 300 columns: one full block of pixels and a partial one; some pixels below black.
  cv::Mat image(7, 300, CV_16UC3), dark(7, 300, CV_16UC3);
  cv::randu(image, cv::Scalar::all(40), cv::Scalar::all(3800));
  cv::randu(dark, cv::Scalar::all(60), cv::Scalar::all(70));
  for (const ModelEvaluation& m : result.summary.models) {
    ASSERT_TRUE(m.usable) << m.spec.Name();
    ApplyOptions options;
    options.exposure_ratio = 1.5;
    const cv::Mat with_dark = ToXyz(m.model, image, dark, options);
    options.black_level = 64.0;
    const cv::Mat with_black = ToXyz(m.model, image, cv::Mat(), options);
    for (int y = 0; y < image.rows; ++y)
      for (int x = 0; x < image.cols; x += 13) {
        const cv::Vec3w p = image.at<cv::Vec3w>(y, x), d = dark.at<cv::Vec3w>(y, x);
        const Eigen::Vector3d rgb(p[2], p[1], p[0]);
        const Eigen::Vector3d a = m.model.ToXyz((rgb - Eigen::Vector3d(d[2], d[1], d[0])) / 1.5);
        const Eigen::Vector3d b = m.model.ToXyz((rgb - Eigen::Vector3d::Constant(64.0)) / 1.5);
        for (int k = 0; k < 3; ++k) {
          EXPECT_NEAR(with_dark.at<cv::Vec3f>(y, x)[k], a[k], 1e-4 * (1.0 + std::abs(a[k]))) << m.spec.Name();
          EXPECT_NEAR(with_black.at<cv::Vec3f>(y, x)[k], b[k], 1e-4 * (1.0 + std::abs(b[k]))) << m.spec.Name();
        }
      }
  }
}

}  // namespace
}  // namespace photorig::solvers::color
