#include "svbrdf_scene.h"

#include <gtest/gtest.h>

#include <string>

namespace photorig::testing {
namespace {

using refl::Method;

TEST(Relighting, MaterialLobesPredictHeldOutLightsBetterThanLambertian) {
  const SvbrdfScene scene = MakeScene(ThreeMaterials());
  refl::RelightingOptions options;
  options.held_out_lights = 4;
  const auto summary = refl::EvaluateHeldOutLights(options, scene.stack, scene.truth.normals, scene.mask);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  EXPECT_EQ(summary.materials, 3);
  ASSERT_EQ(summary.held_out.size(), 4u);
  ASSERT_EQ(summary.errors.size(), 12u);
  const double lambertian = summary.mean_rmse[static_cast<int>(Method::kLambertian)];
  const double material = summary.mean_rmse[static_cast<int>(Method::kPerMaterial)];
  EXPECT_LT(material, 0.7 * lambertian);
  // Close to the noise: the read noise is 0.002 and the shot noise 0.5 % of the signal.
  EXPECT_LT(material, 0.006);
  for (const auto& e : summary.errors) EXPECT_GT(e.psnr_db, 0.0);
}

TEST(Relighting, InvalidOptionsAreRefusedBeforeAnyFit) {
  refl::RelightingOptions options;
  options.held_out_lights = -1;
  // An empty stack, which the fit would refuse as kInvalidInput: the options are checked first.
  const auto summary = refl::EvaluateHeldOutLights(options, refl::ReflectanceStack{}, cv::Mat(), cv::Mat());
  EXPECT_EQ(summary.termination, solvers::core::Termination::kInvalidOptions);
  EXPECT_NE(summary.message.find("held_out_lights"), std::string::npos) << summary.message;
}

// More held-out lights than the stack has is refused before any fit, not
// taken silently as every light.
TEST(Relighting, MoreHeldOutLightsThanTheStackHasAreRefused) {
  const SvbrdfScene scene = MakeScene(ThreeMaterials());
  refl::RelightingOptions options;
  options.held_out_lights = scene.stack.light_count() + 1;
  const auto summary = refl::EvaluateHeldOutLights(options, scene.stack, scene.truth.normals, scene.mask);
  EXPECT_EQ(summary.termination, solvers::core::Termination::kInvalidOptions);
  EXPECT_NE(summary.message.find("exceeds the stack's"), std::string::npos) << summary.message;
  EXPECT_TRUE(summary.errors.empty());
}

TEST(Relighting, OnAMatteObjectTheMaterialFitIsLambertianWithinNoise) {
  SceneSpec spec;
  spec.materials = {Matte(), Matte()};
  spec.band_colour = {Eigen::Vector3d(0.8, 0.7, 0.6), Eigen::Vector3d(0.5, 0.7, 0.8)};
  const SvbrdfScene scene = MakeScene(spec);
  refl::RelightingOptions options;
  options.held_out_lights = 3;
  const auto summary = refl::EvaluateHeldOutLights(options, scene.stack, scene.truth.normals, scene.mask);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.message;
  const double lambertian = summary.mean_rmse[static_cast<int>(Method::kLambertian)];
  const double material = summary.mean_rmse[static_cast<int>(Method::kPerMaterial)];
  EXPECT_NEAR(material / lambertian, 1.0, 0.02);
}

TEST(Relighting, TheHeldOutSubsetIsSpreadOverTheDome) {
  const auto lights = DomeLights();
  const std::vector<int> chosen = refl::StratifiedLights(lights, 6);
  ASSERT_EQ(chosen.size(), 6u);
  EXPECT_EQ(chosen.front(), 0);  // the zenith
  // Every pair of chosen lights is farther apart than neighbours on a ring.
  for (std::size_t a = 0; a < chosen.size(); ++a)
    for (std::size_t b = a + 1; b < chosen.size(); ++b)
      EXPECT_GT(std::acos(lights[chosen[a]].dot(lights[chosen[b]])), 0.5) << chosen[a] << " " << chosen[b];
  EXPECT_EQ(refl::StratifiedLights(lights, 0).size(), lights.size());
}

}  // namespace
}  // namespace photorig::testing
