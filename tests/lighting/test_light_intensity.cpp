#include "photorig/solvers/lighting/light_intensity.h"
#include "synthetic_sphere.h"

#include <gtest/gtest.h>

namespace photorig::solvers::lighting {
namespace {

TEST(LightIntensity, RelativeRgbFromAWhiteSphere) {
  testing::SyntheticCamera camera;
  testing::SyntheticSphere sphere;
  sphere.radius_mm = 10.0;
  testing::SyntheticImageOptions options;
  options.width = options.height = 240;
  options.supersample = 2;
  options.background = 0.0;
  options.noise_sigma = 2.0;
  const SphereFitSummary fit = FitSphereSilhouette(testing::RenderSilhouette(camera, sphere, options));
  const SphereGeometry geometry = LocateSphere(CameraModel{}, fit.circle);
  const std::vector<Eigen::Vector3d> directions = {Eigen::Vector3d(0.6, 0.2, 0.77).normalized(),
                                                   Eigen::Vector3d(-0.3, -0.7, 0.65).normalized(),
                                                   Eigen::Vector3d(0.0, 0.1, 0.99).normalized()};
  const std::vector<Eigen::Vector3d> rgb = {{3000, 2800, 2500}, {2000, 2100, 2300}, {2600, 2600, 2600}};
  std::vector<LightIntensityEstimate> estimates;
  for (std::size_t k = 0; k < directions.size(); ++k) {
    options.seed = static_cast<unsigned>(k + 1);
    estimates.push_back(EstimateIntensityFromSphere(
        testing::RenderWhiteSphere(camera, sphere, directions[k], rgb[k], options), geometry, directions[k]));
    ASSERT_TRUE(estimates.back().usable) << estimates.back().note;
    EXPECT_NEAR(estimates.back().rgb.x() / rgb[k].x(), 1.0, 0.005);
    EXPECT_LT(estimates.back().relative_rms_residual, 0.01);
  }
  NormaliseIntensities(&estimates);
  double mean = 0.0;
  for (const auto& v : rgb) mean += v.sum() / 9.0;
  for (std::size_t k = 0; k < rgb.size(); ++k) {
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(estimates[k].rgb(c), rgb[k](c) / mean, 0.005);
  }
}

TEST(LightIntensity, PlaneAndSaturationAndTooFewSamples) {
  const Eigen::Vector3d light = Eigen::Vector3d(0.5, 0.0, 0.87).normalized();
  cv::Mat plane(50, 50, CV_32F, cv::Scalar(1000.0 / M_PI * light.z()));
  LightIntensityEstimate e = EstimateIntensityFromPlane(plane, cv::Mat(), Eigen::Vector3d::UnitZ(), light);
  ASSERT_TRUE(e.usable) << e.note;
  EXPECT_NEAR(e.rgb.y(), 1000.0, 1e-3);

  DiffuseIntensityOptions options;
  options.saturation_level = 100.0;  // below every sample: nothing left to fit
  e = EstimateIntensityFromPlane(plane, cv::Mat(), Eigen::Vector3d::UnitZ(), light, options);
  EXPECT_FALSE(e.usable);
  EXPECT_EQ(e.samples_saturated, 2500);
  e = EstimateIntensityFromPlane(plane, cv::Mat(), Eigen::Vector3d::UnitZ(), Eigen::Vector3d(1, 0, 0.1));
  EXPECT_FALSE(e.usable) << "grazing light leaves no sample above min_cosine";
}

}  // namespace
}  // namespace photorig::solvers::lighting
