#include "photorig/solvers/ps/evaluation.h"
#include "photorig/solvers/ps/lambertian.h"
#include "lambertian_tiles.h"
#include "ps_test_scene.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>
#include <vector>

namespace photorig::solvers::ps {
namespace {

using testing::RandomSurface;
using testing::RenderStack;
using testing::RingLights;

// The subset kernels this CPU runs, with their names.
std::vector<std::pair<internal::SubsetKernel, const char*>> SubsetKernels() {
  std::vector<std::pair<internal::SubsetKernel, const char*>> kernels;
  for (const auto& [kernel, name] : {std::pair{internal::SubsetKernel::kPortable, "portable subset kernel"},
                                     std::pair{internal::SubsetKernel::kAvx2, "AVX2 subset kernel"},
                                     std::pair{internal::SubsetKernel::kAvx512, "AVX-512 subset kernel"}})
    if (internal::SubsetKernelAvailable(kernel)) kernels.emplace_back(kernel, name);
  return kernels;
}

std::vector<double> Scales(int count, double base = 1000.0) {
  std::vector<double> scales;
  for (int i = 0; i < count; ++i) scales.push_back(base * (0.8 + 0.4 * i / std::max(1, count - 1)));
  return scales;
}

TEST(Lambertian, RecoversNormalsAndAlbedoExactlyWithoutShadows) {
  // Tilts up to 20 deg and lights above 60 deg elevation: every sample is lit.
  const auto truth = RandomSurface(64, 48, 20.0);
  const auto lights = RingLights(12, 60, 80);
  const PhotometricStack stack = RenderStack(truth, lights, Scales(12), 64.0f);
  NormalMap map;
  const SolverSummary summary = SolveLambertian(LambertianOptions{}, stack, &map);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  EXPECT_EQ(summary.pixels_solved, 64u * 48u);
  EXPECT_EQ(summary.samples_rejected, 0u);
  const AngularErrorStats stats = CompareNormals(map.normals, truth.normals);
  EXPECT_EQ(stats.pixels_evaluated, 64u * 48u);
  EXPECT_LT(stats.max_deg, 0.01);
  cv::Mat albedo_error;
  cv::absdiff(map.albedo, truth.albedo, albedo_error);
  double worst = 0;
  cv::minMaxLoc(albedo_error, nullptr, &worst);
  EXPECT_LT(worst, 1e-4);
}

TEST(Lambertian, ExcludesAttachedShadowsPerPixel) {
  // Tilts up to 70 deg under low lights: many samples are in attached shadow.
  const auto truth = RandomSurface(64, 64, 70.0);
  const auto lights = RingLights(24, 20, 70);
  const PhotometricStack stack = RenderStack(truth, lights, Scales(24), 10.0f);
  NormalMap map;
  const SolverSummary summary = SolveLambertian(LambertianOptions{}, stack, &map);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  EXPECT_GT(summary.samples_rejected, 0u);
  EXPECT_GT(summary.pixels_on_light_subsets, 1u);
  const AngularErrorStats stats = CompareNormals(map.normals, truth.normals);
  EXPECT_EQ(stats.pixels_unresolved, summary.pixels_too_few_lights + summary.pixels_ill_conditioned);
  EXPECT_LT(stats.max_deg, 0.01);

  // Plain L2 keeps the clamped zeros and is biased on the same data.
  LambertianOptions l2;
  l2.exclude_unusable_samples = false;
  NormalMap biased;
  ASSERT_TRUE(SolveLambertian(l2, stack, &biased).IsSolutionUsable());
  EXPECT_GT(CompareNormals(biased.normals, truth.normals).mean_deg, 1.0);
}

// The confidence is expected / observed residual variance. The observed RSS
// comes from the normal equations' float sums where their rounding is
// negligible next to it, and from summing the residuals themselves where it
// is not (a fit closer than float sums resolve). Either way it must match the
// RSS of the same light subset summed in double.
TEST(Lambertian, ConfidenceMatchesResidualsSummedInDoubleAtEveryNoiseLevel) {
  const auto truth = RandomSurface(64, 64, 70.0);
  const auto lights = RingLights(24, 20, 70);
  const double scale = 1000.0;
  const float dark = 10.0f;
  // Every subset kernel's float sums this CPU runs.
  for (const auto& [kernel, name] : SubsetKernels())
  for (const double noise_sigma : {2.0, 0.02}) {
    SCOPED_TRACE(noise_sigma);
    SCOPED_TRACE(name);
    internal::UseSubsetKernel(kernel);
    PhotometricStack stack = testing::RenderShinyStack(truth, lights, scale, {}, dark, noise_sigma);
    // A read noise well below the real one keeps every confidence below the
    // clamp at 1, so it is proportional to 1 / RSS.
    stack.noise.read_sigma = 0.1 * noise_sigma;
    LambertianOptions options;
    options.shadow_threshold = 5.0 * noise_sigma;
    NormalMap map;
    ASSERT_TRUE(SolveLambertian(options, stack, &map).IsSolutionUsable());
    std::vector<double> relative_errors;
    for (int p = 0; p < static_cast<int>(truth.albedo.total()); ++p) {
      if (map.flags.ptr<std::uint8_t>()[p] != static_cast<std::uint8_t>(PixelFlag::kSolved)) continue;
      const testing::UsableLeastSquares reference =
          testing::SolveUsableInDouble(stack, p, scale, dark, options.shadow_threshold);
      const int n = reference.usable;
      if (n <= 3) continue;
      const double rss = reference.rss;
      const double read_variance = stack.noise.read_sigma * stack.noise.read_sigma / (scale * scale);
      const double expected = read_variance * n * (n - 3.0) / n;
      ASSERT_LT(expected / rss, 1.0) << "pixel " << p;
      relative_errors.push_back(std::abs(map.confidence.ptr<float>()[p] / (expected / rss) - 1.0));
    }
    ASSERT_GT(relative_errors.size(), 3000u);
    std::sort(relative_errors.begin(), relative_errors.end());
    // Documented: within 4 % at worst, typically a few parts in a thousand.
    EXPECT_LT(relative_errors.back(), 0.04);
    EXPECT_LT(relative_errors[relative_errors.size() / 2], 0.005);
  }
  internal::UseFastestSubsetKernel();
}

TEST(Lambertian, ExcludesSaturatedSamples) {
  const auto truth = RandomSurface(32, 32, 30.0);
  const auto lights = RingLights(16, 50, 85);
  const float saturation = 250.0f;  // clips the brightest samples of bright pixels
  const PhotometricStack stack = RenderStack(truth, lights, Scales(16), 5.0f, saturation);
  LambertianOptions options;
  options.saturation_level = saturation;
  NormalMap map;
  const SolverSummary summary = SolveLambertian(options, stack, &map);
  ASSERT_TRUE(summary.IsSolutionUsable());
  EXPECT_GT(summary.samples_rejected, 0u);
  EXPECT_LT(CompareNormals(map.normals, truth.normals).max_deg, 0.01);
}

TEST(Lambertian, FlagsPixelsWithFewerThanThreeLitSamples) {
  const auto truth = RandomSurface(16, 16, 10.0);
  auto stack = RenderStack(truth, RingLights(8, 50, 80), Scales(8), 0.0f);
  // Pixel (3, 5) is lit by two lights only.
  for (int k = 2; k < 8; ++k) stack.images[k].at<float>(5, 3) = 0.0f;
  NormalMap map;
  const SolverSummary summary = SolveLambertian(LambertianOptions{}, stack, &map);
  ASSERT_TRUE(summary.IsSolutionUsable());
  EXPECT_EQ(map.flags.at<std::uint8_t>(5, 3), static_cast<int>(PixelFlag::kTooFewLights));
  EXPECT_TRUE(std::isnan(map.normals.at<cv::Vec3f>(5, 3)[0]));
  EXPECT_EQ(summary.pixels_too_few_lights, 1u);
  EXPECT_EQ(map.usable_lights.at<std::uint16_t>(5, 3), 2);
}

TEST(Lambertian, FlagsPixelsWhoseLitLightsAreCoplanar) {
  // Lights 0..3 share one azimuth plane (y = 0); the rest are elsewhere.
  std::vector<Eigen::Vector3d> lights = {
      Eigen::Vector3d(1, 0, 1).normalized(), Eigen::Vector3d(-1, 0, 1).normalized(),
      Eigen::Vector3d(0.3, 0, 1).normalized(), Eigen::Vector3d(-0.5, 0, 1).normalized(),
      Eigen::Vector3d(0, 1, 1).normalized(), Eigen::Vector3d(0, -1, 1).normalized()};
  const auto truth = RandomSurface(8, 8, 5.0);
  auto stack = RenderStack(truth, lights, std::vector<double>(6, 100.0), 0.0f);
  stack.images[4].at<float>(2, 2) = 0.0f;
  stack.images[5].at<float>(2, 2) = 0.0f;
  NormalMap map;
  const SolverSummary summary = SolveLambertian(LambertianOptions{}, stack, &map);
  ASSERT_TRUE(summary.IsSolutionUsable());
  EXPECT_EQ(map.flags.at<std::uint8_t>(2, 2), static_cast<int>(PixelFlag::kIllConditioned));
  EXPECT_EQ(summary.pixels_ill_conditioned, 1u);
  EXPECT_EQ(summary.pixels_solved, 63u);
}

TEST(Lambertian, RefusesFewerThanThreeLights) {
  const auto truth = RandomSurface(8, 8, 5.0);
  const auto stack = RenderStack(truth, RingLights(2, 50, 60), Scales(2), 0.0f);
  NormalMap map;
  const SolverSummary summary = SolveLambertian(LambertianOptions{}, stack, &map);
  EXPECT_FALSE(summary.IsSolutionUsable());
  EXPECT_NE(summary.message.find("at least 3 lights"), std::string::npos) << summary.message;
}

TEST(Lambertian, RefusesCoplanarLightsAndReportsTheConditionNumber) {
  // All lights in the x-z plane: the y component of n is unobservable.
  std::vector<Eigen::Vector3d> lights;
  for (double angle : {-50.0, -20.0, 0.0, 25.0, 55.0})
    lights.emplace_back(std::sin(angle * M_PI / 180), 0.0, std::cos(angle * M_PI / 180));
  const auto truth = RandomSurface(8, 8, 5.0);
  const auto stack = RenderStack(truth, lights, Scales(5), 0.0f);
  NormalMap map;
  const SolverSummary summary = SolveLambertian(LambertianOptions{}, stack, &map);
  EXPECT_FALSE(summary.IsSolutionUsable());
  EXPECT_NE(summary.message.find("coplanar"), std::string::npos) << summary.message;
  EXPECT_GT(summary.condition_number, 1e3);
}

TEST(Lambertian, NearlyCoplanarLightsAreRejectedAboveTheConfiguredCondition) {
  std::vector<Eigen::Vector3d> lights;
  for (double angle : {-50.0, 0.0, 55.0})
    lights.push_back(Eigen::Vector3d(std::sin(angle * M_PI / 180), 0.0, std::cos(angle * M_PI / 180)));
  lights.push_back(Eigen::Vector3d(0.0, 0.02, 1.0).normalized());  // barely out of the plane
  const auto truth = RandomSurface(8, 8, 5.0);
  const auto stack = RenderStack(truth, lights, Scales(4), 0.0f);
  NormalMap map;
  LambertianOptions strict;
  strict.max_condition_number = 20.0;
  EXPECT_FALSE(SolveLambertian(strict, stack, &map).IsSolutionUsable());
  LambertianOptions lenient;
  lenient.max_condition_number = 1e4;
  const SolverSummary summary = SolveLambertian(lenient, stack, &map);
  EXPECT_TRUE(summary.IsSolutionUsable());
  EXPECT_GT(summary.condition_number, 20.0);
}

TEST(Lambertian, RejectsImagesOfDifferentSizesNamingTheImage) {
  const auto truth = RandomSurface(8, 8, 5.0);
  auto stack = RenderStack(truth, RingLights(4, 50, 60), Scales(4), 0.0f);
  stack.images[3] = cv::Mat::zeros(9, 8, CV_32F);
  NormalMap map;
  const SolverSummary summary = SolveLambertian(LambertianOptions{}, stack, &map);
  EXPECT_FALSE(summary.IsSolutionUsable());
  EXPECT_NE(summary.message.find("image 3 is 8x9"), std::string::npos) << summary.message;
}

TEST(Lambertian, HonoursTheMask) {
  const auto truth = RandomSurface(16, 16, 10.0);
  auto stack = RenderStack(truth, RingLights(6, 50, 80), Scales(6), 0.0f);
  stack.mask = cv::Mat::zeros(16, 16, CV_8U);
  stack.mask(cv::Rect(4, 4, 5, 5)).setTo(255);
  NormalMap map;
  const SolverSummary summary = SolveLambertian(LambertianOptions{}, stack, &map);
  EXPECT_EQ(summary.pixels_solved, 25u);
  EXPECT_EQ(summary.pixels_outside_mask, 256u - 25u);
  EXPECT_EQ(map.flags.at<std::uint8_t>(0, 0), static_cast<int>(PixelFlag::kOutsideMask));
}

// Whole chunks of pixels outside the mask are skipped, not solved and then
// discarded: what lies there (here NaN and clipped garbage) changes nothing,
// and every pixel inside gets exactly the answer of the unmasked solve, with
// and without the exclusion of unusable samples.
TEST(Lambertian, SkipsWhatTheMaskLeavesOutWithoutChangingWhatItKeeps) {
  const int width = 300, height = 90;
  const auto truth = RandomSurface(width, height, 60.0);
  const auto clean = RenderStack(truth, RingLights(20, 20, 80), Scales(20), 3.0f);
  auto masked = clean;
  masked.mask = cv::Mat::zeros(height, width, CV_8U);
  cv::circle(masked.mask, cv::Point(width / 2, height / 2), 40, cv::Scalar(255), cv::FILLED);
  for (auto& image : masked.images) {
    image = image.clone();
    image.setTo(std::numeric_limits<float>::quiet_NaN(), masked.mask == 0);
    image.row(0).setTo(1e30f);  // the top row is outside the circle
  }
  const int inside = cv::countNonZero(masked.mask);
  for (const bool exclude : {true, false}) {
    SCOPED_TRACE(exclude ? "usable samples" : "every sample (l2)");
    LambertianOptions options;
    options.shadow_threshold = 5.0;
    options.exclude_unusable_samples = exclude;
    NormalMap reference, map;
    ASSERT_TRUE(SolveLambertian(options, clean, &reference).IsSolutionUsable());
    const SolverSummary summary = SolveLambertian(options, masked, &map);
    ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
    EXPECT_EQ(summary.pixels_outside_mask, static_cast<std::size_t>(width * height - inside));
    EXPECT_EQ(summary.pixels_solved + summary.pixels_too_few_lights + summary.pixels_ill_conditioned,
              static_cast<std::size_t>(inside));
    int differing = 0;
    for (int p = 0; p < width * height; ++p) {
      const bool in = masked.mask.ptr<std::uint8_t>()[p] != 0;
      const std::uint8_t flag = map.flags.ptr<std::uint8_t>()[p];
      if (!in) {
        EXPECT_EQ(flag, static_cast<std::uint8_t>(PixelFlag::kOutsideMask)) << p;
        EXPECT_EQ(map.usable_lights.ptr<std::uint16_t>()[p], 0) << p;
        continue;
      }
      const cv::Vec3f a = map.normals.ptr<cv::Vec3f>()[p], b = reference.normals.ptr<cv::Vec3f>()[p];
      differing += flag != reference.flags.ptr<std::uint8_t>()[p] ||
                   (flag == 0 && (a != b || map.confidence.ptr<float>()[p] != reference.confidence.ptr<float>()[p]));
    }
    EXPECT_EQ(differing, 0);
  }
}

TEST(Lambertian, ResultDoesNotDependOnTheThreadCount) {
  const auto truth = RandomSurface(80, 70, 60.0);
  const auto stack = RenderStack(truth, RingLights(20, 20, 80), Scales(20), 3.0f);
  LambertianOptions one, two;
  one.num_threads = 1;
  two.num_threads = 2;
  NormalMap a, b;
  ASSERT_TRUE(SolveLambertian(one, stack, &a).IsSolutionUsable());
  ASSERT_TRUE(SolveLambertian(two, stack, &b).IsSolutionUsable());
  EXPECT_EQ(cv::countNonZero(a.flags != b.flags), 0);
  cv::Mat diff;
  cv::absdiff(a.normals.reshape(1), b.normals.reshape(1), diff);
  cv::patchNaNs(diff, 0.0);
  EXPECT_EQ(cv::countNonZero(diff), 0);
}

// Each tile starts on the path its thread's previous tile suggests (lit
// pixels by the pseudo-inverse, or every pixel on its own subset), and the two
// round differently. A fully lit chunk must come out the same whichever came
// first: tiles that alternate between lit and partly shadowed, solved with
// different thread counts, put different predecessors before many tiles.
TEST(Lambertian, FullyLitPixelsDoNotDependOnTheTileSolvedBefore) {
  auto truth = RandomSurface(128, 256, 20.0);  // 32 tiles of 8 rows; lights at >= 30 deg elevation light every pixel
  for (int tile = 0; tile < 32; tile += 3)
    for (int c = 0; c < 128; c += 2)  // a shadowed row: tilted 85 deg, away from half the lights
      truth.normals.at<cv::Vec3f>(8 * tile + 3, c) = cv::Vec3f(0.9962f, 0.0f, 0.0872f);
  const auto stack = RenderStack(truth, RingLights(24, 30, 80), Scales(24), 3.0f);
  NormalMap reference;
  LambertianOptions options;
  options.num_threads = 1;
  ASSERT_TRUE(SolveLambertian(options, stack, &reference).IsSolutionUsable());
  for (int threads : {2, 3, 4}) {
    options.num_threads = threads;
    NormalMap map;
    ASSERT_TRUE(SolveLambertian(options, stack, &map).IsSolutionUsable());
    EXPECT_EQ(cv::countNonZero(map.flags != reference.flags), 0) << threads;
    EXPECT_EQ(std::memcmp(map.normals.data, reference.normals.data, map.normals.total() * map.normals.elemSize()), 0)
        << threads << " threads";
    EXPECT_EQ(std::memcmp(map.confidence.data, reference.confidence.data,
                          map.confidence.total() * map.confidence.elemSize()),
              0)
        << threads << " threads";
  }
}

// The subset kernel's intrinsic versions sum G_S per group of lights from a
// table (four lights with AVX-512, three with AVX2), the portable loop light
// by light: the same equations, rounded differently. A row width that is no
// multiple of the 16 or 8 lanes, a light count that is no multiple of four
// or three, shadows, clipping and noise exercise every edge of each.
TEST(Lambertian, IntrinsicAndPortableSubsetKernelsAgree) {
  const auto truth = RandomSurface(61, 37, 70.0);
  const PhotometricStack stack =
      testing::RenderShinyStack(truth, RingLights(23, 15, 75), 3000.0, {}, 10.0f, 2.0);
  LambertianOptions options;
  options.shadow_threshold = 6.0;
  options.saturation_level = 700.0;  // clips where albedo cos > 0.72
  LambertianOptions unclipped = options;
  unclipped.saturation_level = std::numeric_limits<double>::infinity();
  internal::UseSubsetKernel(internal::SubsetKernel::kPortable);
  NormalMap portable, shadows_only;
  ASSERT_LT(SolveLambertian(unclipped, stack, &shadows_only).samples_rejected + 500,
            SolveLambertian(options, stack, &portable).samples_rejected);
  const SolverSummary portable_summary = SolveLambertian(options, stack, &portable);
  ASSERT_TRUE(portable_summary.IsSolutionUsable()) << portable_summary.message;
  EXPECT_GT(portable_summary.pixels_on_light_subsets, 1000u);
  EXPECT_GT(portable_summary.samples_rejected, 5000u);
  int compared = 0;
  for (const auto& [kernel, name] : SubsetKernels()) {
    if (kernel == internal::SubsetKernel::kPortable) continue;
    SCOPED_TRACE(name);
    ++compared;
    internal::UseSubsetKernel(kernel);
    NormalMap fast;
    const SolverSummary fast_summary = SolveLambertian(options, stack, &fast);
    ASSERT_TRUE(fast_summary.IsSolutionUsable()) << fast_summary.message;
    EXPECT_EQ(fast_summary.samples_rejected, portable_summary.samples_rejected);
    EXPECT_EQ(cv::countNonZero(fast.flags != portable.flags), 0);
    EXPECT_EQ(cv::countNonZero(fast.usable_lights != portable.usable_lights), 0);
    EXPECT_LT(CompareNormals(fast.normals, portable.normals).max_deg, 1e-3);
    for (int p = 0; p < static_cast<int>(truth.albedo.total()); ++p) {
      if (fast.flags.ptr<std::uint8_t>()[p] != static_cast<std::uint8_t>(PixelFlag::kSolved)) continue;
      ASSERT_NEAR(fast.albedo.ptr<float>()[p], portable.albedo.ptr<float>()[p], 1e-5 * portable.albedo.ptr<float>()[p])
          << "pixel " << p;
      // The residual from the sums, b^2 - 2 x^T r + x^T G x, cancels: both
      // kernels are within a few per cent of the RSS summed in double (see
      // ConfidenceMatchesResidualsSummedInDoubleAtEveryNoiseLevel).
      ASSERT_NEAR(fast.confidence.ptr<float>()[p], portable.confidence.ptr<float>()[p], 0.01) << "pixel " << p;
    }
  }
  internal::UseFastestSubsetKernel();
  if (compared == 0) GTEST_SKIP() << "this CPU has neither AVX2 with FMA nor AVX-512F";
}

TEST(LambertianOptions, ValidationExplainsTheProblem) {
  LambertianOptions options;
  std::string why;
  EXPECT_TRUE(options.IsValid(&why));
  options.shadow_threshold = -1;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("shadow_threshold"), std::string::npos);
  options = LambertianOptions{};
  options.max_condition_number = 0.5;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("max_condition_number"), std::string::npos);
}

}  // namespace
}  // namespace photorig::solvers::ps
