// The joint refinement of normals and reflectance never leaves the normals
// further from the truth than it found them, on the scenes of three recipes
// (captured by the simulator, solved as `photorig solve svbrdf
// --refine-normals` solves them: photometric stereo's `auto` normals, the
// CLI's default). Where the refined normals predict the held-out lights no
// better, the given ones are kept, and the report says which.
#include "photorig/daemon/service/run.h"
#include "photorig/daemon/pipelines/svbrdf_pipeline.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>

namespace photorig::testing {
namespace {

namespace fs = std::filesystem;

struct RecipeScene {
  const char* recipe;
  // A window of the object solved (x, y, width, height); empty: the whole
  // object. The large spheres' 90,000 pixels take a minute; a window of
  // their surface shows the same normals.
  cv::Rect window;
};

class RefinementOnRecipe : public ::testing::TestWithParam<RecipeScene> {};

TEST_P(RefinementOnRecipe, RefinedNormalsAreNoFurtherFromTheTruth) {
  const RecipeScene scene = GetParam();
  const fs::path out = fs::temp_directory_path() /
                       ("refine-" + fs::path(scene.recipe).stem().string() + "-" + std::to_string(::getpid()));
  fs::remove_all(out);
  daemon::RunRequest run;
  run.recipe_path = std::string(PHOTORIG_SOURCE_DIR) + "/config/recipes/" + scene.recipe;
  run.output_directory = out.string();
  run.solve = false;
  const daemon::RunOutcome captured = daemon::ExecuteRun(run);
  ASSERT_EQ(captured.capture.status, daemon::CaptureStatus::kComplete) << captured.capture.reason;

  daemon::PhotometricStereoInput input = daemon::LoadRunStack(out.string());
  ASSERT_FALSE(input.truth_normals.empty());
  if (!scene.window.empty()) {
    cv::Mat window(input.truth_normals.size(), CV_8U, cv::Scalar(0));
    window(scene.window).setTo(255);
    input.object_mask = input.object_mask.empty() ? window : (input.object_mask & window);
  }
  config::SvbrdfRequest request;  // the CLI's defaults: `auto` normals, 4 materials at most
  request.refine_normals = true;
  request.held_out_lights = -1;
  request.export_gltf = false;
  const fs::path results = out / "svbrdf";
  const daemon::SvbrdfResult result = daemon::SolveSvbrdfAndWrite(input, request, results.string());
  ASSERT_TRUE(result.usable()) << result.summary.message;
  ASSERT_TRUE(result.normal_refinement.has_value());
  const auto& refinement = *result.normal_refinement;
  ASSERT_TRUE(refinement.IsSolutionUsable()) << refinement.message;
  ASSERT_TRUE(result.unrefined_normals_vs_truth_mean_deg && result.refined_normals_vs_truth_mean_deg);
  const double before = *result.unrefined_normals_vs_truth_mean_deg, after = *result.refined_normals_vs_truth_mean_deg;
  std::printf("%s: normals %.4f -> %.4f deg, held-out RMSE given %.5g refined %.5g, kept %s\n", scene.recipe, before,
              after, refinement.held_out_rmse_given, refinement.held_out_rmse_refined,
              refinement.kept_refined ? "refined" : "given");
  EXPECT_LE(after, before);
  // The choice follows the held-out error, and the normals returned are the ones it names.
  EXPECT_EQ(refinement.kept_refined, refinement.held_out_rmse_refined < refinement.held_out_rmse_given);
  if (!refinement.kept_refined) {
    EXPECT_EQ(after, before);
    EXPECT_FALSE(fs::exists(results / "normals.tiff"));
  } else {
    EXPECT_TRUE(fs::exists(results / "normals.tiff"));
  }
  // The report says which normals were kept and why.
  std::ifstream file(results / "report.json");
  const nlohmann::json report = nlohmann::json::parse(file);
  EXPECT_EQ(report["normal_refinement"]["kept"], refinement.kept_refined ? "refined" : "given");
  EXPECT_DOUBLE_EQ(report["normal_refinement"]["held_out_rmse"]["given"].get<double>(), refinement.held_out_rmse_given);
  EXPECT_DOUBLE_EQ(report["normal_refinement"]["normals_vs_truth_mean_deg"]["after"].get<double>(), after);
  fs::remove_all(out);
}

INSTANTIATE_TEST_SUITE_P(Recipes, RefinementOnRecipe,
                         ::testing::Values(RecipeScene{"ps-sphere.yaml", cv::Rect(150, 150, 64, 64)},
                                           RecipeScene{"ps-bumps.yaml", cv::Rect(120, 120, 96, 96)},
                                           RecipeScene{"svbrdf-dome.yaml", cv::Rect()}),
                         [](const auto& info) {
                           std::string name = fs::path(info.param.recipe).stem().string();
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

}  // namespace
}  // namespace photorig::testing
