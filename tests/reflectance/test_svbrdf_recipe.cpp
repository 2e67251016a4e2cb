// config/recipes/svbrdf-dome.yaml through ExecuteRun (what `photorig run`
// calls): a colour capture of a sphere painted matte and glossy, then the
// svbrdf solve stage, whose materials, held-out errors and glTF asset are checked.
#include "photorig/daemon/run.h"

#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <tiny_gltf.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

namespace photorig::testing {
namespace {

namespace fs = std::filesystem;
namespace refl = solvers::reflectance;

TEST(SvbrdfRecipe, FindsTheMatteAndTheGlossyPaintAndWritesALoadableAsset) {
  const fs::path out = fs::temp_directory_path() / ("svbrdf-recipe-" + std::to_string(::getpid()));
  fs::remove_all(out);
  daemon::RunRequest request;
  request.recipe_path = std::string(PHOTORIG_SOURCE_DIR) + "/config/recipes/svbrdf-dome.yaml";
  request.output_directory = out.string();
  const daemon::RunOutcome outcome = daemon::ExecuteRun(request);
  ASSERT_EQ(outcome.capture.status, daemon::CaptureStatus::kComplete) << outcome.capture.reason;
  ASSERT_TRUE(outcome.svbrdf.has_value());
  const daemon::SvbrdfResult& result = *outcome.svbrdf;
  ASSERT_TRUE(result.usable()) << result.summary.message;

  // The glossy paint: a Blinn-Phong lobe in every channel. The matte paint: a
  // material over at least a third of the pixels with next to no lobe.
  const auto glossy = std::max_element(result.material_fits.begin(), result.material_fits.end(),
                                       [](const auto& a, const auto& b) { return a.specular.minCoeff() < b.specular.minCoeff(); });
  EXPECT_EQ(glossy->model, solvers::brdf::Model::kBlinnPhong);
  EXPECT_GT(glossy->specular.minCoeff(), 0.1);
  EXPECT_GT(glossy->pixels, result.summary.pixels_fitted / 3);
  const bool matte_found = std::any_of(result.material_fits.begin(), result.material_fits.end(), [&](const auto& m) {
    return m.pixels > result.summary.pixels_fitted / 3 && m.specular.maxCoeff() < 0.01;
  });
  EXPECT_TRUE(matte_found);
  RecordProperty("materials", result.summary.materials);

  ASSERT_TRUE(result.relighting && result.relighting->IsSolutionUsable());
  const auto& rmse = result.relighting->mean_rmse;
  EXPECT_LT(rmse[static_cast<int>(refl::Method::kPerMaterial)], 0.5 * rmse[static_cast<int>(refl::Method::kLambertian)]);

  ASSERT_FALSE(result.gltf_path.empty());
  tinygltf::TinyGLTF loader;
  tinygltf::Model model;
  std::string error, warning;
  ASSERT_TRUE(loader.LoadASCIIFromFile(&model, &error, &warning, result.gltf_path)) << error;
  ASSERT_EQ(model.meshes.size(), 1u);
  EXPECT_FALSE(model.materials.empty());
  EXPECT_FALSE(model.meshes[0].primitives.empty());
  fs::remove_all(out);
}

}  // namespace
}  // namespace photorig::testing
