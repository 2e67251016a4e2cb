// Near-light photometric stereo against a sphere rendered here with the
// physics written out (inverse square, LED axis, Lambert's cosine): the
// distant model's error on a small dome, the near model's, its rounds and the
// depth it places.

#include "photorig/solvers/ps/evaluation.h"
#include "photorig/solvers/ps/near_lights.h"
#include "photorig/solvers/ps/photometric_stereo.h"

#include "ps_test_scene.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace photorig::solvers::ps {
namespace {

constexpr double kRadiusMm = 17.0;
constexpr double kPitchMm = 0.3;
constexpr int kSize = 128;

struct NearScene {
  PhotometricStack stack;
  std::vector<NearLight> lights;
  cv::Mat normals, height_mm;  // truth
};

// A Lambertian sphere of albedo 0.6 centred on the origin (its rim on the
// sample plane) under LEDs on a hemisphere of `dome_radius_mm`, each aimed at
// the origin, Lambertian emitters (cos^1) of unit irradiance there.
NearScene RenderNearSphere(double dome_radius_mm, double noise_sigma = 0.0) {
  NearScene scene;
  for (const Eigen::Vector3d& direction : testing::RingLights(40, 25, 75))
    scene.lights.push_back({dome_radius_mm * direction, -direction, 1.0});
  scene.normals = cv::Mat(kSize, kSize, CV_32FC3, cv::Scalar::all(0));
  scene.height_mm = cv::Mat(kSize, kSize, CV_32F, cv::Scalar(std::nanf("")));
  scene.stack.mask = cv::Mat::zeros(kSize, kSize, CV_8U);
  std::mt19937 rng(11);
  std::normal_distribution<float> noise(0.0f, static_cast<float>(noise_sigma));
  for (std::size_t k = 0; k < scene.lights.size(); ++k) scene.stack.images.emplace_back(kSize, kSize, CV_32F, cv::Scalar(0));
  for (int r = 0; r < kSize; ++r)
    for (int c = 0; c < kSize; ++c) {
      const double x = (c + 0.5 - 0.5 * kSize) * kPitchMm, y = (0.5 * kSize - r - 0.5) * kPitchMm;
      const double rho2 = x * x + y * y;
      if (rho2 >= 0.97 * kRadiusMm * kRadiusMm) continue;
      const Eigen::Vector3d point(x, y, std::sqrt(kRadiusMm * kRadiusMm - rho2));
      const Eigen::Vector3d n = point / kRadiusMm;
      scene.normals.at<cv::Vec3f>(r, c) = cv::Vec3f(float(n.x()), float(n.y()), float(n.z()));
      scene.height_mm.at<float>(r, c) = static_cast<float>(point.z());
      scene.stack.mask.at<std::uint8_t>(r, c) = 255;
      for (std::size_t k = 0; k < scene.lights.size(); ++k) {
        const NearLight& led = scene.lights[k];
        const Eigen::Vector3d to = led.position_mm - point;
        const double d = to.norm();
        // Radiant intensity cos(axis angle) I0, with I0 = R^2 so that the
        // irradiance at the origin, straight on the axis, is 1.
        const double irradiance = dome_radius_mm * dome_radius_mm * (-led.axis.dot(to / d)) / (d * d);
        const double value = 0.6 / M_PI * std::max(0.0, n.dot(to / d)) * irradiance * 1000.0;
        scene.stack.images[k].at<float>(r, c) = static_cast<float>(value) + noise(rng);
      }
    }
  for (const NearLight& led : scene.lights) {
    scene.stack.light_directions.push_back(led.position_mm.normalized());
    scene.stack.light_scales.push_back(1000.0);
  }
  if (noise_sigma > 0.0) scene.stack.noise.read_sigma = noise_sigma;
  return scene;
}

PhotometricStereoOptions Lambertian() {
  PhotometricStereoOptions options;
  options.method = Method::kLambertian;
  options.lambertian.shadow_threshold = 1e-3;
  return options;
}

NearLightOptions Near() {
  NearLightOptions options;
  options.pixel_pitch_mm = kPitchMm;
  return options;
}

TEST(NearLights, IrradianceFallsWithTheSquareOfDistanceAndTheCosineToTheAxis) {
  const NearLight led{{0.0, 0.0, 100.0}, {0.0, 0.0, -1.0}, 2.0};
  Eigen::Vector3d towards;
  EXPECT_DOUBLE_EQ(led.RelativeIrradiance(Eigen::Vector3d::Zero(), &towards), 1.0);
  EXPECT_NEAR(led.RelativeIrradiance({0.0, 0.0, 50.0}, &towards), 4.0, 1e-12);
  // 100 mm aside at the plane: distance sqrt(2) x 100 mm, 45 deg off the axis.
  EXPECT_NEAR(led.RelativeIrradiance({100.0, 0.0, 0.0}, &towards), 0.5 * 0.5, 1e-12);
  EXPECT_NEAR(towards.x(), -std::sqrt(0.5), 1e-12);
  EXPECT_EQ(led.RelativeIrradiance({0.0, 0.0, 150.0}, &towards), 0.0);  // behind the LED
}

TEST(NearLights, RecoverTheSphereWhereTheDistantModelTiltsItByDegrees) {
  const NearScene scene = RenderNearSphere(80.0);
  NormalMap distant;
  ASSERT_TRUE(SolvePhotometricStereo(Lambertian(), scene.stack, &distant).IsSolutionUsable());
  const AngularErrorStats distant_error = CompareNormals(distant.normals, scene.normals, scene.stack.mask);
  EXPECT_GT(distant_error.mean_deg, 5.0);

  NormalMap near;
  cv::Mat height;
  const NearLightSummary summary =
      SolveNearLightPhotometricStereo(Lambertian(), Near(), scene.stack, scene.lights, &near, &height);
  ASSERT_EQ(summary.termination, core::Termination::kSuccess) << summary.message;
  const AngularErrorStats error = CompareNormals(near.normals, scene.normals, scene.stack.mask);
  EXPECT_LT(error.mean_deg, 0.3) << "distant model: " << distant_error.mean_deg << " deg";
  EXPECT_GE(summary.rounds, 3);
  EXPECT_LE(summary.rounds, 8);
  ASSERT_EQ(summary.normal_change_deg.size(), static_cast<std::size_t>(summary.rounds - 1));
  EXPECT_LT(summary.normal_change_deg.back(), Near().normal_change_tolerance_deg);
  // The depth is placed where the model fits best: the sphere's true heights.
  cv::Mat difference;
  cv::absdiff(height, scene.height_mm, difference);
  const cv::Mat inside = (scene.stack.mask != 0) & (height == height);
  EXPECT_LT(cv::mean(difference, inside)[0], 0.5);
}

TEST(NearLights, NoiseLeavesTheNearModelWithinHalfADegree) {
  const NearScene scene = RenderNearSphere(150.0, 2.0);  // about 1 % of a mid-grey sample
  PhotometricStereoOptions options = Lambertian();
  options.shadow_threshold_read_sigmas = 3.0;  // as `photorig solve ps` does: noise on a shadow is no light
  NormalMap near;
  cv::Mat height;
  const NearLightSummary summary =
      SolveNearLightPhotometricStereo(options, Near(), scene.stack, scene.lights, &near, &height);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  EXPECT_LT(CompareNormals(near.normals, scene.normals, scene.stack.mask).mean_deg, 0.5);
}

TEST(NearLights, MethodsThatFitOneLightMatrixAreRefusedNotApproximated) {
  const NearScene scene = RenderNearSphere(400.0);
  PhotometricStereoOptions options = Lambertian();
  options.method = Method::kAuto;
  NormalMap near;
  cv::Mat height;
  const NearLightSummary summary = SolveNearLightPhotometricStereo(options, Near(), scene.stack, scene.lights, &near, &height);
  EXPECT_EQ(summary.termination, core::Termination::kInvalidOptions);
  EXPECT_NE(summary.message.find("auto"), std::string::npos) << summary.message;
}

TEST(NearLights, AnLedBelowTheSamplePlaneIsInvalidInput) {
  NearScene scene = RenderNearSphere(400.0);
  scene.lights[3].position_mm.z() = -5.0;
  NormalMap near;
  cv::Mat height;
  const NearLightSummary summary =
      SolveNearLightPhotometricStereo(Lambertian(), Near(), scene.stack, scene.lights, &near, &height);
  EXPECT_EQ(summary.termination, core::Termination::kInvalidInput);
  EXPECT_NE(summary.message.find("near light 3"), std::string::npos) << summary.message;
}

}  // namespace
}  // namespace photorig::solvers::ps
