// Cases the data cannot support, each detected and flagged (docs/reflectance.md).
#include "svbrdf_scene.h"

#include <gtest/gtest.h>

#include <algorithm>

namespace photorig::testing {
namespace {

using refl::Warning;

bool Has(const std::vector<Warning>& list, Warning w) { return std::find(list.begin(), list.end(), w) != list.end(); }

// Keeps only the cap of the sphere whose normals lie within `deg` of the view.
void KeepCap(SvbrdfScene* scene, double deg) {
  for (int r = 0; r < scene->mask.rows; ++r)
    for (int c = 0; c < scene->mask.cols; ++c) {
      const cv::Vec3f n = scene->truth.normals.at<cv::Vec3f>(r, c);
      if (!(n[2] > std::cos(deg * M_PI / 180.0))) scene->mask.at<std::uint8_t>(r, c) = 0;
    }
}

SceneSpec OneGlossy(double exponent) {
  SceneSpec spec;
  spec.channels = 1;
  spec.materials = {Phong(0.3, exponent)};
  return spec;
}

// Lobes the per-material fit has no shape search for are refused by name.
TEST(Stability, LobesFittedOnlyToWholeTablesAreRefused) {
  refl::ReflectanceOptions options;
  std::string why;
  EXPECT_TRUE(options.IsValid(&why)) << why;
  options.lobes = {brdf::Model::kGgx, brdf::Model::kWard};
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("ward"), std::string::npos) << why;
}

TEST(Stability, TooFewLightsOnASpecularLobeAreFlagged) {
  SceneSpec spec = OneGlossy(150.0);
  spec.lights = DomeLights(1, 8, 40.0, 40.0);  // the zenith and a ring: only the zenith lights the cap's highlight
  SvbrdfScene scene = MakeScene(spec);
  KeepCap(&scene, 10.0);
  refl::ReflectanceMaps fit;
  const auto summary = refl::FitReflectance({}, scene.stack, scene.truth.normals, scene.mask, &fit);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  ASSERT_EQ(fit.materials.size(), 1u);
  EXPECT_EQ(fit.materials[0].model, brdf::Model::kBlinnPhong);
  EXPECT_EQ(fit.materials[0].highlight_lights, 1);
  EXPECT_TRUE(Has(summary.warnings, Warning::kTooFewHighlightLights)) << summary.message;
}

TEST(Stability, AMaterialWhoseHighlightsNoLightReachesIsFlagged) {
  SvbrdfScene scene = MakeScene([] {
    SceneSpec spec = OneGlossy(300.0);
    spec.lights = DomeLights(2, 12, 10.0, 20.0);  // low lights only: half vectors >= 35 degrees from the view
    spec.lights.erase(spec.lights.begin());       // and no zenith light
    return spec;
  }());
  KeepCap(&scene, 10.0);
  refl::ReflectanceMaps fit;
  const auto summary = refl::FitReflectance({}, scene.stack, scene.truth.normals, scene.mask, &fit);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  ASSERT_EQ(summary.materials, 1);
  EXPECT_EQ(fit.materials[0].model, brdf::Model::kLambertian);
  EXPECT_TRUE(Has(fit.materials[0].warnings, Warning::kHighlightsUnobserved));
  EXPECT_GT(fit.materials[0].min_half_angle_deg, 20.0);
}

TEST(Stability, SaturatedHighlightsAreLeftOutAndFlagged) {
  SceneSpec spec = OneGlossy(60.0);
  SvbrdfScene scene = MakeScene(spec);
  scene.stack.saturation_level = 0.8;
  for (auto& image : scene.stack.images) cv::min(image, 0.8f, image);
  refl::ReflectanceMaps fit;
  refl::ReflectanceOptions options;
  options.max_materials = 2;  // enough to see whether clipped pixels split off, and shorter
  const auto summary = refl::FitReflectance(options, scene.stack, scene.truth.normals, scene.mask, &fit);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  EXPECT_GT(summary.saturated_samples, 0);
  EXPECT_TRUE(Has(summary.warnings, Warning::kSaturatedHighlights));
  // The clipped samples are not fitted as if they were the peak: the
  // material holding most pixels keeps the true lobe. (Pixels whose every
  // highlight was clipped may form a material of their own.)
  const auto most = std::max_element(fit.materials.begin(), fit.materials.end(),
                                     [](const auto& a, const auto& b) { return a.pixels < b.pixels; });
  EXPECT_EQ(most->model, brdf::Model::kBlinnPhong);
  EXPECT_NEAR(most->shape / 60.0, 1.0, 0.15);
}

TEST(Stability, AnUncalibratedLightIntensityIsFlagged) {
  SvbrdfScene scene = MakeScene(ThreeMaterials(1));
  scene.stack.images[5] *= 1.4;
  refl::ReflectanceMaps fit;
  refl::ReflectanceOptions options;
  options.max_materials = 3;  // the scene's count, to keep the test short
  const auto summary = refl::FitReflectance(options, scene.stack, scene.truth.normals, scene.mask, &fit);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  EXPECT_TRUE(Has(summary.warnings, Warning::kInconsistentIntensities));
  EXPECT_EQ(summary.inconsistent_lights, std::vector<int>{5});
  EXPECT_NEAR(summary.light_intensity_ratio[5], 1.4, 0.08);
  // A calibrated stack raises nothing.
  const auto clean = refl::FitReflectance(options, MakeScene(ThreeMaterials(1)).stack, scene.truth.normals, scene.mask, &fit);
  EXPECT_FALSE(Has(clean.warnings, Warning::kInconsistentIntensities));
}

}  // namespace
}  // namespace photorig::testing
