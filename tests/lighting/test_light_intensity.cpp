#include "photorig/solvers/lighting/light_intensity.h"
#include "synthetic_sphere.h"

#include <gtest/gtest.h>

namespace photorig::solvers::lighting {
namespace {

TEST(LightIntensity, RelativeRgbFromAWhiteSphere) {
  testing::WhiteSphereScene scene = testing::MakeWhiteSphereScene(100.0, 240, 2.0);
  const std::vector<Eigen::Vector3d> directions = {Eigen::Vector3d(0.6, 0.2, 0.77).normalized(),
                                                   Eigen::Vector3d(-0.3, -0.7, 0.65).normalized(),
                                                   Eigen::Vector3d(0.0, 0.1, 0.99).normalized()};
  const std::vector<Eigen::Vector3d> rgb = {{3000, 2800, 2500}, {2000, 2100, 2300}, {2600, 2600, 2600}};
  std::vector<LightIntensityEstimate> estimates;
  for (std::size_t k = 0; k < directions.size(); ++k) {
    scene.options.seed = static_cast<unsigned>(k + 1);
    estimates.push_back(EstimateIntensityFromSphere(scene.Render(directions[k], rgb[k]), scene.geometry, directions[k]));
    ASSERT_TRUE(estimates.back().usable) << estimates.back().note;
    EXPECT_NEAR(estimates.back().rgb.x() / rgb[k].x(), 1.0, 0.005);
    EXPECT_LT(estimates.back().relative_rms_residual, 0.01);
    // The residuals are the noise: no shading left unexplained.
    EXPECT_LT(estimates.back().model_error, 0.005);
    // The worst channel's noise against the channels' mean residual (their levels differ by up to 20 %).
    EXPECT_GT(estimates.back().relative_noise_rms, 0.9 * estimates.back().relative_rms_residual);
    EXPECT_LT(estimates.back().relative_noise_rms, 1.3 * estimates.back().relative_rms_residual);
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

// The noise estimate from adjacent samples, against the noise added: a
// plane's samples at one level, sigma 3 DN on 300 DN (1 %).
TEST(LightIntensity, NoiseFromAdjacentSamplesMatchesTheNoiseAdded) {
  const Eigen::Vector3d light = Eigen::Vector3d(0.3, 0.2, 0.93).normalized();
  const double level = 300.0;
  cv::Mat plane(120, 120, CV_32F);
  cv::randn(plane, cv::Scalar(level), cv::Scalar(3.0));
  DiffuseIntensityOptions options;
  const LightIntensityEstimate e = EstimateIntensityFromPlane(plane, cv::Mat(), Eigen::Vector3d::UnitZ(), light, options);
  ASSERT_TRUE(e.usable) << e.note;
  EXPECT_NEAR(e.rgb.x(), level * M_PI / light.z(), 0.002 * level * M_PI / light.z());
  EXPECT_NEAR(e.relative_noise_rms, 0.01, 0.0005);  // 14,280 pairs: the estimate's own spread is 0.6 %
  EXPECT_LT(e.model_error, 0.002);
}

// A dim 8-bit frame: its peak about 20 DN, read noise 1.5 DN and rounding
// to whole DN leave residuals of 9 % of the mean sample, all of them noise.
// A limit on the relative residual would refuse it; the model error
// (residual beyond the noise) accepts it, and the intensity is right.
TEST(LightIntensity, ADim8BitFrameIsNoiseNotAModelError) {
  const testing::WhiteSphereScene scene = testing::MakeWhiteSphereScene(100.0, 240, 1.5);
  const Eigen::Vector3d light = Eigen::Vector3d(0.4, -0.3, 0.87).normalized();
  const Eigen::Vector3d rgb(65.0, 60.0, 55.0);
  cv::Mat frame;
  scene.Render(light, rgb).convertTo(frame, CV_8UC3);  // rounds to whole DN
  const LightIntensityEstimate e = EstimateIntensityFromSphere(frame, scene.geometry, light);
  ASSERT_TRUE(e.usable) << e.note;
  EXPECT_GT(e.relative_rms_residual, 0.06);
  EXPECT_LT(e.model_error, 0.02);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(e.rgb(c) / rgb(c), 1.0, 0.02) << "channel " << c;
}

// What is not a matte target is refused, with the reason: a sheen (a
// Blinn-Phong lobe of 10 % of the albedo, exponent 20) and a cast shadow
// over a third of the sphere each leave shading the fit cannot explain,
// while the noise estimate stays at the noise.
TEST(LightIntensity, AGlossyOrShadowedTargetIsRefused) {
  const testing::WhiteSphereScene scene = testing::MakeWhiteSphereScene(100.0, 240, 2.0);
  const Eigen::Vector3d light = Eigen::Vector3d(0.5, 0.1, 0.86).normalized();
  const Eigen::Vector3d rgb(3000.0, 2900.0, 2800.0);
  const LightIntensityEstimate glossy = EstimateIntensityFromSphere(scene.Render(light, rgb, 0.1, 20.0), scene.geometry, light);
  EXPECT_FALSE(glossy.usable);
  EXPECT_GT(glossy.model_error, 0.05);
  EXPECT_LT(glossy.relative_noise_rms, 0.01);
  EXPECT_NE(glossy.note.find("departs from a matte surface's"), std::string::npos) << glossy.note;

  cv::Mat shadowed = scene.Render(light, rgb);
  shadowed.colRange(0, 100).setTo(cv::Scalar::all(0.0));
  const LightIntensityEstimate shadow = EstimateIntensityFromSphere(shadowed, scene.geometry, light);
  EXPECT_FALSE(shadow.usable);
  EXPECT_GT(shadow.model_error, 0.05);
  EXPECT_LT(shadow.relative_noise_rms, 0.01);

  DiffuseIntensityOptions lenient;
  lenient.max_model_error = 1.0;
  EXPECT_TRUE(EstimateIntensityFromSphere(shadowed, scene.geometry, light, lenient).usable);
  lenient.max_model_error = 0.0;
  std::string why;
  EXPECT_FALSE(lenient.IsValid(&why));
  EXPECT_NE(why.find("max_model_error"), std::string::npos);
}

}  // namespace
}  // namespace photorig::solvers::lighting
