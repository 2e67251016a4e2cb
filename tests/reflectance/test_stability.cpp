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


// Two paints of different colours and lobes: the glossy Blinn-Phong band on
// the left, a GGX band on the right. `one_sided`: only lights on the left
// whose half vectors lie 22 degrees or more left of the plane x = 0, so none
// comes within 20 degrees of a right-band normal (or within 2 degrees of the
// band's edge at the pixel grid): the GGX paint's highlights are never seen.
SvbrdfScene TwoGlossyPaints(bool one_sided, int channels = 3) {
  SceneSpec spec;
  spec.channels = channels;
  spec.materials = {Phong(0.35, 60.0), Ggx(0.25, 0.25)};
  spec.band_colour = {Eigen::Vector3d(0.4, 0.7, 0.9), Eigen::Vector3d(0.9, 0.6, 0.4)};
  spec.lights = DomeLights(4, 24, 25.0, 45.0);
  if (one_sided)
    spec.lights.erase(std::remove_if(spec.lights.begin(), spec.lights.end(),
                                     [](const Eigen::Vector3d& l) {
                                       // Keep a light only if its half vector lies 22 degrees or more beyond x = 0.
                                       const Eigen::Vector3d h = (l + Eigen::Vector3d::UnitZ()).normalized();
                                       return h.x() > -std::sin(22.0 * M_PI / 180.0);
                                     }),
                      spec.lights.end());
  return MakeScene(spec);
}

// Per true band: the fitted material most of its pixels went to, and the
// fraction of its fitted pixels that saw a highlight.
struct BandFit {
  int material = -1;
  double on_material = 0.0, seen = 0.0;
};
BandFit BandOf(const SvbrdfScene& scene, const refl::ReflectanceMaps& fit, int band) {
  std::vector<int> votes(fit.materials.size(), 0);
  int pixels = 0, seen = 0;
  for (int i = 0; i < static_cast<int>(scene.truth.material.total()); ++i) {
    const int m = fit.material.at<std::uint8_t>(i);
    if (scene.truth.material.at<std::uint8_t>(i) != band || m >= static_cast<int>(fit.materials.size())) continue;
    ++votes[m];
    ++pixels;
    seen += fit.highlight_seen.at<std::uint8_t>(i) == 1;
  }
  BandFit out;
  out.material = static_cast<int>(std::max_element(votes.begin(), votes.end()) - votes.begin());
  out.on_material = static_cast<double>(votes[out.material]) / std::max(1, pixels);
  out.seen = static_cast<double>(seen) / std::max(1, pixels);
  return out;
}

// The reflectance fit of a two-paint scene, free to find up to three materials.
refl::ReflectanceSummary FitUpToThreeMaterials(const SvbrdfScene& scene, refl::ReflectanceOptions* options,
                                               refl::ReflectanceMaps* fit) {
  options->max_materials = 3;
  return refl::FitReflectance(*options, scene.stack, scene.truth.normals, scene.mask, fit);
}

// Before, the GGX paint's pixels (no lobe seen) joined the glossy paint's
// material and were reported with its Blinn-Phong lobe, unflagged.
TEST(Stability, APaintWhoseHighlightsNoLightReachesIsFlaggedNotMerged) {
  const SvbrdfScene scene = TwoGlossyPaints(true);
  refl::ReflectanceMaps fit;
  refl::ReflectanceOptions options;
  const auto summary = FitUpToThreeMaterials(scene, &options, &fit);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  ASSERT_EQ(summary.materials, 2) << summary.message;
  EXPECT_EQ(summary.materials_unobserved, 1);
  const BandFit glossy = BandOf(scene, fit, 0), unseen = BandOf(scene, fit, 1);
  ASSERT_NE(glossy.material, unseen.material);
  EXPECT_GT(glossy.on_material, 0.97);
  EXPECT_GT(unseen.on_material, 0.9);  // measured 0.955 (blends along the edge go by their lobe)
  // The lit paint's lobe is measured, unflagged.
  const refl::MaterialFit& g = fit.materials[glossy.material];
  EXPECT_EQ(g.model, brdf::Model::kBlinnPhong);
  EXPECT_NEAR(g.shape / 60.0, 1.0, 0.05);
  EXPECT_FALSE(Has(g.warnings, Warning::kHighlightsUnobserved));
  EXPECT_GT(glossy.seen, 0.5);
  // The other's is not: flagged, per material and per pixel, and not the glossy paint's lobe.
  const refl::MaterialFit& u = fit.materials[unseen.material];
  EXPECT_TRUE(Has(u.warnings, Warning::kHighlightsUnobserved));
  EXPECT_TRUE(Has(summary.warnings, Warning::kHighlightsUnobserved));
  EXPECT_LT(2 * u.highlight_pixels, u.pixels);
  EXPECT_EQ(unseen.seen, 0.0);
  EXPECT_GT(u.min_half_angle_deg, options.unobserved_half_angle_deg);
  EXPECT_FALSE(u.model == g.model && u.shape == g.shape);
  EXPECT_GT(summary.pixels_highlight_unseen, u.pixels / 2);
}

// In monochrome nothing but position tells the unseen paint apart: its
// pixels join the material beside them, which then holds mostly pixels that
// saw no highlight and is flagged; the pixels themselves say so.
TEST(Stability, InMonochromeAnUnseenPaintJoinsItsNeighboursFlagged) {
  const SvbrdfScene scene = TwoGlossyPaints(true, 1);
  refl::ReflectanceMaps fit;
  refl::ReflectanceOptions options;
  const auto summary = FitUpToThreeMaterials(scene, &options, &fit);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  // Measured: one material (Blinn-Phong, e 60), 424 of its 1,310 pixels saw a highlight.
  ASSERT_EQ(summary.materials, 1);
  EXPECT_TRUE(Has(fit.materials[0].warnings, Warning::kHighlightsUnobserved));
  EXPECT_LT(2 * fit.materials[0].highlight_pixels, fit.materials[0].pixels);
  EXPECT_EQ(BandOf(scene, fit, 1).seen, 0.0);
  EXPECT_GT(BandOf(scene, fit, 0).seen, 0.5);
}

// The control: every light, so both paints' highlights are seen.
TEST(Stability, TwoPaintsWhoseHighlightsAreAllObservedRaiseNothing) {
  const SvbrdfScene scene = TwoGlossyPaints(false);
  refl::ReflectanceMaps fit;
  refl::ReflectanceOptions options;
  const auto summary = FitUpToThreeMaterials(scene, &options, &fit);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  ASSERT_EQ(summary.materials, 2);
  EXPECT_EQ(summary.materials_unobserved, 0);
  EXPECT_TRUE(summary.warnings.empty()) << summary.message;
  const BandFit phong = BandOf(scene, fit, 0), ggx = BandOf(scene, fit, 1);
  ASSERT_NE(phong.material, ggx.material);
  EXPECT_EQ(fit.materials[phong.material].model, brdf::Model::kBlinnPhong);
  EXPECT_EQ(fit.materials[ggx.material].model, brdf::Model::kGgx);
  EXPECT_NEAR(fit.materials[ggx.material].shape / 0.25, 1.0, 0.05);
  EXPECT_GT(phong.seen, 0.5);
  EXPECT_GT(ggx.seen, 0.5);
}

}  // namespace
}  // namespace photorig::testing
