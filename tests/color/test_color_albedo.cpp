// Colour albedo from photometric stereo on an RGB stack, corrected by a model
// calibrated from the chart: normals solved once on luminance, each channel's
// albedo fitted with them fixed, then camera RGB -> XYZ.

#include "photorig/solvers/color/apply.h"
#include "photorig/solvers/color/calibration.h"
#include "photorig/solvers/color/colorimetry.h"
#include "photorig/solvers/ps/channel_albedo.h"
#include "photorig/solvers/ps/lambertian.h"
#include "photorig/sim/renderer.h"
#include "photorig/sim/scene.h"
#include "sim_chart.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace photorig::solvers::color {
namespace {

constexpr int kSize = 96;
// Six chromatic patches and a grey, painted as vertical stripes across a sphere.
constexpr int kStripePatches[] = {0, 2, 5, 10, 13, 14, 21};
constexpr int kStripes = static_cast<int>(std::size(kStripePatches));

int StripeOf(int x) { return x * kStripes / kSize; }

// The per-channel albedo of the painted sphere: each patch's camera signal
// (the chart render's units, white = 1 in the top channel).
struct ColourSphere {
  sim::SurfaceMaps surface;
  std::array<cv::Mat, 3> albedo;  // r, g, b
};

ColourSphere PaintedSphere(const sim::ChartRender& chart) {
  sim::Scene scene;
  scene.shape = sim::Scene::Shape::kSphere;
  scene.ApplyShapeDefaults(kSize * 0.1);
  scene.sphere_radius_mm = 4.7;
  scene.cast_shadows = false;
  ColourSphere sphere{sim::SampleSurface(scene, kSize, kSize, 0.1), {}};
  const sim::ChartGeometry geometry;
  for (int c = 0; c < 3; ++c) {
    sphere.albedo[static_cast<std::size_t>(c)] = sphere.surface.albedo.clone();
    for (int y = 0; y < kSize; ++y)
      for (int x = 0; x < kSize; ++x) {
        const cv::Rect rect = geometry.PatchRect(kStripePatches[StripeOf(x)]);
        const float signal = chart.signal.at<cv::Vec3f>(rect.y + rect.height / 2, rect.x + rect.width / 2)[c];
        float& a = sphere.albedo[static_cast<std::size_t>(c)].at<float>(y, x);
        if (std::isfinite(a)) a = signal;
      }
  }
  return sphere;
}

TEST(ColourAlbedo, CorrectedPhotometricStereoAlbedoMatchesTheChartCalibratedTarget) {
  // The chart capture and its model.
  const sim::SensorModel sensor;
  const sim::ChartRender chart = testing::RenderChart("nikon-5100", Illuminant::kD65);
  LocateOptions locate;
  locate.use_detector = false;
  locate.fixed_corners = sim::ChartGeometry{}.GridCorners();
  CalibrationOptions calibration;
  calibration.candidates = {*ModelSpec::Parse("linear"), *ModelSpec::Parse("root-poly-2")};
  const ChartCalibration calibrated = CalibrateChartImage(chart.raw, chart.dark, Illuminant::kD65, locate,
                                                          testing::SimMeasureOptions(chart), calibration);
  ASSERT_TRUE(calibrated.summary.IsSolutionUsable()) << calibrated.summary.message;
  const ColorModel& model = calibrated.summary.chosen_model();
  const double chart_dn_per_signal = sensor.DnPerRadiance(sim::ExposureForWhite(sensor, 0.8), 0.0);

  // The same camera photographs the painted sphere under 12 white lights, one
  // frame per light and channel (independent noise per channel).
  const ColourSphere sphere = PaintedSphere(chart);
  std::vector<sim::Light> lights;
  std::vector<Eigen::Vector3d> directions;
  for (int k = 0; k < 12; ++k) {
    const double azimuth = 2.0 * M_PI * k / 12.0, elevation = (k % 2 ? 40.0 : 65.0) * M_PI / 180.0;
    directions.emplace_back(std::cos(elevation) * std::cos(azimuth), std::cos(elevation) * std::sin(azimuth),
                            std::sin(elevation));
    lights.emplace_back(directions.back(), 1.0);
  }
  const double exposure_us = 0.8 * sensor.full_well_e / sensor.response_e_per_us;
  const double dn_per_radiance = sensor.DnPerRadiance(exposure_us, 0.0);
  std::array<solvers::ps::PhotometricStack, 3> channels;
  solvers::ps::PhotometricStack luminance;
  for (int c = 0; c < 3; ++c) {
    // The renderer reads rho_d from the BRDF parameters.
    sim::SurfaceMaps surface = sphere.surface;
    surface.brdf_params = sphere.surface.brdf_params.clone();
    cv::Mat planes[4];
    cv::split(surface.brdf_params, planes);
    planes[0] = sphere.albedo[static_cast<std::size_t>(c)];
    cv::merge(planes, 4, surface.brdf_params);
    for (int k = 0; k < 12; ++k) {
      std::vector<double> levels(12, 0.0);
      levels[static_cast<std::size_t>(k)] = 1.0;
      cv::Mat radiance = sim::RenderRadiance(surface, false, lights, levels);
      cv::patchNaNs(radiance, 0.0);
      const std::vector<std::uint16_t> dn =
          sim::ExposeFrame(sensor, radiance, exposure_us, 0.0, 5, static_cast<std::uint64_t>(3 * k + c));
      cv::Mat frame;
      cv::Mat(kSize, kSize, CV_16U, const_cast<std::uint16_t*>(dn.data())).convertTo(frame, CV_32F);
      channels[static_cast<std::size_t>(c)].images.push_back(frame);
      if (c == 0) luminance.images.push_back(frame / 3.0);
      else luminance.images[static_cast<std::size_t>(k)] += frame / 3.0;
    }
  }
  for (solvers::ps::PhotometricStack* stack : {&channels[0], &channels[1], &channels[2], &luminance}) {
    stack->dark = cv::Mat(kSize, kSize, CV_32F, cv::Scalar(sensor.black_level_dn));
    stack->light_directions = directions;
    // DN per unit radiance times the irradiance (1), as the PS pipeline builds them.
    stack->light_scales.assign(12, dn_per_radiance);
    stack->mask = sphere.surface.mask;
  }
  solvers::ps::NormalMap normals;
  solvers::ps::LambertianOptions lambertian;
  lambertian.shadow_threshold = 20.0;
  ASSERT_TRUE(solvers::ps::SolveLambertian(lambertian, luminance, &normals).IsSolutionUsable());

  std::array<cv::Mat, 3> albedo;
  // No shadow threshold here: with the normal known, unlit samples are those
  // with n . w < min_cosine, and cutting dim samples on their noisy value would
  // bias a dark channel's albedo upwards.
  const solvers::ps::ChannelAlbedoOptions options;
  for (int c = 0; c < 3; ++c) {
    const solvers::ps::SolverSummary summary =
        solvers::ps::SolveChannelAlbedo(options, channels[static_cast<std::size_t>(c)], normals.normals, &albedo[static_cast<std::size_t>(c)]);
    ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  }
  // Camera-RGB albedo in B, G, R order, as a chart capture would be: the chart's
  // DN per unit signal is the exposure ratio between them.
  cv::Mat albedo_bgr;
  cv::merge(std::vector<cv::Mat>{albedo[2], albedo[1], albedo[0]}, albedo_bgr);
  ApplyOptions apply;
  apply.exposure_ratio = 1.0 / chart_dn_per_signal;
  cv::Mat xyz;
  ASSERT_TRUE(CameraToXyz(model, albedo_bgr, cv::Mat(), apply, &xyz).IsSolutionUsable());

  const ChartReference reference = ColorCheckerReference(Illuminant::kD65, ReferenceGrid());
  const sim::ChartGeometry geometry;
  for (int stripe = 0; stripe < kStripes; ++stripe) {
    const int patch = kStripePatches[stripe];
    // Per stripe: mean over pixels facing the camera (|n_z| > 0.5) well inside the stripe.
    Eigen::Vector3d mean_xyz = Eigen::Vector3d::Zero(), mean_rgb = Eigen::Vector3d::Zero();
    int pixels = 0;
    for (int y = 0; y < kSize; ++y)
      for (int x = stripe * kSize / kStripes + 2; x < (stripe + 1) * kSize / kStripes - 2; ++x) {
        const cv::Vec3f n = normals.normals.at<cv::Vec3f>(y, x);
        const cv::Vec3f v = xyz.at<cv::Vec3f>(y, x);
        if (!(n[2] > 0.5) || !std::isfinite(v[0])) continue;
        mean_xyz += Eigen::Vector3d(v[0], v[1], v[2]);
        for (int c = 0; c < 3; ++c) mean_rgb[c] += albedo[static_cast<std::size_t>(c)].at<float>(y, x);
        ++pixels;
      }
    ASSERT_GT(pixels, 20) << "patch " << patch + 1;
    mean_xyz /= pixels;
    mean_rgb /= pixels;
    // Each channel's albedo within 1.5 % of the painted one.
    const cv::Rect rect = geometry.PatchRect(patch);
    const cv::Vec3f truth = chart.signal.at<cv::Vec3f>(rect.y + rect.height / 2, rect.x + rect.width / 2);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean_rgb[c], truth[c], 0.015 * truth[c] + 1e-3) << "patch " << patch + 1;
    // The corrected albedo is the model's answer for the painted colour (what
    // the chart calibration makes of it) to within noise ...
    const Eigen::Vector3d target = model.ToXyz(chart_dn_per_signal * Eigen::Vector3d(truth[0], truth[1], truth[2]));
    const double de_target = Ciede2000(XyzToLab(mean_xyz, model.white_xyz), XyzToLab(target, model.white_xyz));
    EXPECT_LT(de_target, 0.5) << "patch " << patch + 1;
    // ... and the patch's true colour to within the calibration's own error.
    const double de_truth = Ciede2000(XyzToLab(mean_xyz, model.white_xyz),
                                      XyzToLab(reference.xyz[static_cast<std::size_t>(patch)], reference.white_xyz));
    EXPECT_LT(de_truth, 2.0) << "patch " << patch + 1;
  }
}

TEST(ColourAlbedo, MissingNormalsAndDarkChannelsAreFlaggedNotGuessed) {
  solvers::ps::PhotometricStack stack;
  for (int k = 0; k < 3; ++k) {
    stack.images.push_back(cv::Mat(2, 2, CV_32F, cv::Scalar(k == 0 ? 100.0 : 0.0)));
    stack.light_directions.push_back(Eigen::Vector3d(k == 1 ? 0.6 : 0.0, k == 2 ? 0.6 : 0.0, k == 0 ? 1.0 : 0.8));
  }
  stack.light_scales.assign(3, 1.0);
  cv::Mat normals(2, 2, CV_32FC3, cv::Vec3f(0, 0, 1));
  normals.at<cv::Vec3f>(0, 0) = cv::Vec3f(NAN, NAN, NAN);
  cv::Mat albedo;
  solvers::ps::ChannelAlbedoOptions options;
  options.min_samples = 2;
  // Two of three samples are zero (shadowed): too few usable samples.
  solvers::ps::SolverSummary summary = solvers::ps::SolveChannelAlbedo(options, stack, normals, &albedo);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  EXPECT_EQ(summary.pixels_solved, 0u);
  EXPECT_EQ(summary.pixels_too_few_lights, 3u);
  EXPECT_TRUE(std::isnan(albedo.at<float>(0, 0)));
  options.min_samples = 1;
  summary = solvers::ps::SolveChannelAlbedo(options, stack, normals, &albedo);
  EXPECT_EQ(summary.pixels_solved, 3u);
  EXPECT_NEAR(albedo.at<float>(1, 1), M_PI * 100.0, 1e-3);  // b = rho / pi * 1
  EXPECT_TRUE(std::isnan(albedo.at<float>(0, 0)));
  // Wrong-sized normals are refused.
  EXPECT_FALSE(solvers::ps::SolveChannelAlbedo(options, stack, cv::Mat(3, 3, CV_32FC3), &albedo).IsSolutionUsable());
}

}  // namespace
}  // namespace photorig::solvers::color

namespace photorig::solvers::color {
namespace {

// RGB frames with every kind of sample (lit, shadowed, clipped, grazing) and
// a pixel without a normal, solved for all channels at once and channel by
// channel: the same albedo to the last bit and the same counts.
TEST(ColourAlbedo, AllChannelsAtOnceAnswerAsEachChannelAlone) {
  constexpr int kLights = 9, kRows = 5, kCols = 7;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::vector<cv::Mat> frames;
  std::vector<Eigen::Vector3d> directions, scales;
  std::array<solvers::ps::PhotometricStack, 3> channels;
  for (int k = 0; k < kLights; ++k) {
    directions.push_back(Eigen::Vector3d(0.5 * unit(rng), 0.5 * unit(rng), 1.0).normalized());
    scales.push_back(Eigen::Vector3d(1.0 + 0.3 * unit(rng), 0.8, 1.2 + 0.1 * k));
    cv::Mat frame(kRows, kCols, CV_32FC3);
    for (int y = 0; y < kRows; ++y)
      for (int x = 0; x < kCols; ++x)
        for (int c = 0; c < 3; ++c) {
          // 100 +- 90 DN, some at 0 (shadow) and some clipped (+infinity).
          const double roll = unit(rng);
          frame.at<cv::Vec3f>(y, x)[c] = roll > 0.85   ? std::numeric_limits<float>::infinity()
                                         : roll < -0.8 ? 0.0f
                                                       : static_cast<float>(100.0 + 90.0 * unit(rng));
        }
    frames.push_back(frame);
    std::vector<cv::Mat> split;
    cv::split(frame, split);
    for (int c = 0; c < 3; ++c) {
      channels[c].images.push_back(split[c]);
      channels[c].light_directions.push_back(directions.back());
      channels[c].light_scales.push_back(scales.back()(c));
    }
  }
  cv::Mat normals(kRows, kCols, CV_32FC3);
  for (int y = 0; y < kRows; ++y)
    for (int x = 0; x < kCols; ++x) {
      const Eigen::Vector3d n = Eigen::Vector3d(0.6 * unit(rng), 0.6 * unit(rng), 1.0).normalized();
      normals.at<cv::Vec3f>(y, x) = cv::Vec3f(float(n.x()), float(n.y()), float(n.z()));
    }
  normals.at<cv::Vec3f>(2, 3) = cv::Vec3f(NAN, NAN, NAN);
  std::array<solvers::ps::ChannelAlbedoOptions, 3> options;
  for (int c = 0; c < 3; ++c) {
    options[c].shadow_threshold = 5.0 * (c + 1);
    options[c].min_cosine = 0.2 + 0.2 * c;  // the blue channel drops the grazing lights
    options[c].min_samples = 3;
    options[c].saturation_level = c == 1 ? 180.0 : std::numeric_limits<double>::infinity();
  }
  cv::Mat together;
  const std::array<solvers::ps::SolverSummary, 3> summaries =
      solvers::ps::SolveRgbAlbedo(options, frames, directions, scales, normals, &together);
  ASSERT_EQ(together.type(), CV_32FC3);
  std::size_t solved = 0;
  for (int c = 0; c < 3; ++c) {
    ASSERT_TRUE(summaries[c].IsSolutionUsable()) << summaries[c].message;
    cv::Mat alone;
    const solvers::ps::SolverSummary summary = solvers::ps::SolveChannelAlbedo(options[c], channels[c], normals, &alone);
    ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
    cv::Mat channel;
    cv::extractChannel(together, channel, c);
    for (int y = 0; y < kRows; ++y)
      for (int x = 0; x < kCols; ++x) {
        const float a = alone.at<float>(y, x), b = channel.at<float>(y, x);
        EXPECT_TRUE(a == b || (std::isnan(a) && std::isnan(b))) << "channel " << c << " at " << x << "," << y;
      }
    EXPECT_EQ(summaries[c].pixels_solved, summary.pixels_solved);
    EXPECT_EQ(summaries[c].pixels_too_few_lights, summary.pixels_too_few_lights);
    EXPECT_EQ(summaries[c].pixels_outside_mask, 1u);
    EXPECT_EQ(summaries[c].samples_rejected, summary.samples_rejected);
    EXPECT_GT(summary.samples_rejected, 0u);
    solved += summary.pixels_solved;
  }
  // The case is not empty: most pixels have an albedo, some have too few samples.
  EXPECT_GT(solved, 3u * kRows * kCols / 2);
  // Frames that do not fit their lights are refused in every channel's summary.
  std::vector<Eigen::Vector3d> two_scales(scales.begin(), scales.begin() + 2);
  const std::array<solvers::ps::SolverSummary, 3> refused =
      solvers::ps::SolveRgbAlbedo(options, frames, directions, two_scales, normals, &together);
  for (const solvers::ps::SolverSummary& summary : refused) {
    EXPECT_FALSE(summary.IsSolutionUsable());
    EXPECT_NE(summary.message.find("light scales"), std::string::npos) << summary.message;
  }
}

}  // namespace
}  // namespace photorig::solvers::color
