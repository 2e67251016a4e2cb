// FitReflectance (materials, lobes and albedos) on the simulated three-material
// colour scene of the tests, by the scene's side in pixels.
#include "svbrdf_scene.h"

#include <benchmark/benchmark.h>

namespace {

using namespace photorig::testing;

void BM_FitReflectance(benchmark::State& state) {
  SceneSpec spec = ThreeMaterials();
  spec.size = static_cast<int>(state.range(0));
  const SvbrdfScene scene = MakeScene(spec);
  for (auto _ : state) {
    refl::ReflectanceMaps fit;
    const auto summary = refl::FitReflectance({}, scene.stack, scene.truth.normals, scene.mask, &fit);
    if (!summary.IsSolutionUsable()) state.SkipWithError(summary.message.c_str());
    benchmark::DoNotOptimize(fit.albedo.data);
  }
  state.counters["pixels"] = cv::countNonZero(scene.mask);
}
BENCHMARK(BM_FitReflectance)->Arg(24)->Arg(48)->Unit(benchmark::kMillisecond)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
