// The svbrdf solve of config/recipes/svbrdf-dome.yaml on its captured stack,
// capture excluded: what `photorig run` spends after the last frame
// (photometric stereo, the reflectance fit, the refit within the materials,
// the normal refinement, the held-out check and the glTF asset). The stack
// is captured once by the simulator into a scratch folder; each iteration
// loads it and solves, as the solve stage does.
//   bench_svbrdf_recipe --benchmark_repetitions=3 (wall and process CPU time; counters: stage times, ms)
#include "photorig/config/recipe.h"
#include "photorig/config/solve_requests.h"
#include "photorig/daemon/service/run.h"
#include "photorig/daemon/pipelines/svbrdf_pipeline.h"

#include <benchmark/benchmark.h>
#include <unistd.h>

#include <filesystem>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;

void BM_SvbrdfRecipeSolve(benchmark::State& state) {
  const std::string recipe_path = std::string(PHOTORIG_SOURCE_DIR) + "/config/recipes/svbrdf-dome.yaml";
  const fs::path run = fs::temp_directory_path() / ("bench-svbrdf-recipe-" + std::to_string(::getpid()));
  fs::remove_all(run);
  RunRequest capture;
  capture.recipe_path = recipe_path;
  capture.output_directory = run.string();
  capture.solve = false;
  const RunOutcome captured = ExecuteRun(capture);
  if (captured.capture.status != CaptureStatus::kComplete) {
    state.SkipWithError(("capture failed: " + captured.capture.reason).c_str());
    return;
  }
  const config::Recipe recipe = config::LoadRecipe(recipe_path, config::LoadRigConfig(config::RecipeRigPath(recipe_path, "")));
  SvbrdfResult result;
  for (auto _ : state) {
    result = SolveSvbrdfAndWrite(LoadRunStack(run.string()), *recipe.svbrdf, (run / "results" / "svbrdf").string());
    if (!result.usable()) state.SkipWithError(result.summary.message.c_str());
  }
  state.counters["pixels"] = result.summary.pixels_fitted;
  if (result.normal_refinement) {
    state.counters["refine_ms"] = result.normal_refinement->total_ms;
    state.counters["refine_judge_ms"] = result.normal_refinement->judge_ms;
    state.counters["kept_refined"] = result.normal_refinement->kept_refined;
    if (result.refined_normals_vs_truth_mean_deg) {
      state.counters["normals_deg_given"] = *result.unrefined_normals_vs_truth_mean_deg;
      state.counters["normals_deg_kept"] = *result.refined_normals_vs_truth_mean_deg;
    }
    state.counters["reduced_chi_square"] = result.summary.reduced_chi_square;
  }
  if (result.relighting) state.counters["held_out_ms"] = result.relighting->total_ms;
  fs::remove_all(run);
}
BENCHMARK(BM_SvbrdfRecipeSolve)->Unit(benchmark::kSecond)->Iterations(1)->MeasureProcessCPUTime()->UseRealTime();

}  // namespace
}  // namespace photorig::daemon

BENCHMARK_MAIN();
