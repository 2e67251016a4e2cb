// Rendering speed of the simulator at one megapixel. Compare BM_ShadowedHeightfield
// with BM_MemoryPass (one read and one write of the frame) from the same run.
#include "photorig/sim/devices.h"
#include "photorig/sim/renderer.h"
#include "photorig/sim/world.h"

#include <benchmark/benchmark.h>

#include <cmath>

namespace photorig::sim {
namespace {

constexpr int kSide = 1024;

Scene Bumps(Brdf::Model model) {
  Scene scene;
  scene.shape = Scene::Shape::kBumps;
  scene.bumps = Scene::DefaultBumps(kSide * 0.05);
  scene.material.model = model;
  return scene;
}

void BM_MemoryPass(benchmark::State& state) {
  cv::Mat in(kSide, kSide, CV_32F, cv::Scalar(0.5f)), out(kSide, kSide, CV_32F);
  for (auto _ : state) {
    cv::multiply(in, 2.0, out);
    benchmark::DoNotOptimize(out.data);
  }
}
BENCHMARK(BM_MemoryPass)->Unit(benchmark::kMillisecond);

void BM_ShadowedHeightfield(benchmark::State& state) {
  const auto model = static_cast<Brdf::Model>(state.range(0));
  const Scene scene = Bumps(model);
  const SurfaceMaps maps = SampleSurface(scene, kSide, kSide, 0.05);
  const auto brdf = scene.material.MakeBrdf();
  const std::vector<Light> lights = {{Eigen::Vector3d(0.8, 0.3, 0.5).normalized(), 1.0}};
  for (auto _ : state) benchmark::DoNotOptimize(RenderRadiance(maps, *brdf, true, lights, {1.0}).data);
  state.SetLabel(Brdf::ModelName(model));
}
BENCHMARK(BM_ShadowedHeightfield)
    ->Arg(int(Brdf::Model::kLambertian))
    ->Arg(int(Brdf::Model::kBlinnPhong))
    ->Arg(int(Brdf::Model::kGgx))
    ->Unit(benchmark::kMillisecond);

// One bounce of inter-reflection over the same 1 MP heightfield, per sample
// count: the cost is linear in the samples and the march length.
void BM_OneBounce(benchmark::State& state) {
  const SurfaceMaps maps = SampleSurface(Bumps(Brdf::Model::kLambertian), kSide, kSide, 0.05);
  const auto brdf = MakeBrdf(Brdf::Model::kLambertian);
  const cv::Mat direct = RenderRadiance(maps, true, {{Eigen::Vector3d(0.8, 0.3, 0.5).normalized(), 1.0}}, {1.0});
  const int samples = static_cast<int>(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(RenderOneBounce(maps, *brdf, direct, samples, 1).data);
  state.counters["rays_per_s"] = benchmark::Counter(static_cast<double>(kSide) * kSide * samples,
                                                    benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_OneBounce)->Arg(4)->Arg(16)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ShadowSweep(benchmark::State& state) {
  const SurfaceMaps maps = SampleSurface(Bumps(Brdf::Model::kLambertian), kSide, kSide, 0.05);
  for (auto _ : state)
    benchmark::DoNotOptimize(CastShadowMask(maps, Eigen::Vector3d(0.8, 0.3, 0.5).normalized()).data);
}
BENCHMARK(BM_ShadowSweep)->Unit(benchmark::kMillisecond);

// 96 LEDs, one frame each, through the simulated controller and camera
// (render + sensor noise + frame hand-over).
void BM_Capture96Lights(benchmark::State& state) {
  WorldConfig config;
  config.scene = Bumps(Brdf::Model::kLambertian);
  config.camera = {kSide, kSide, 0.05};
  for (int k = 0; k < 96; ++k) {
    const double azimuth = 2 * M_PI * k / 24, elevation = (20 + 20 * (k / 24)) * M_PI / 180;
    config.lights.push_back({Eigen::Vector3d(std::cos(elevation) * std::cos(azimuth),
                                             std::cos(elevation) * std::sin(azimuth), std::sin(elevation)),
                             1.0});
  }
  auto world = std::make_shared<World>(config);
  SimLightDome dome("dome", world);
  SimCamera camera("camera", world);
  drivers::CameraSettings settings;
  settings.exposure_us = 10000;
  if (!dome.Open().ok() || !camera.Open().ok() || !camera.Configure(settings).ok() || !camera.Start().ok()) {
    state.SkipWithError("devices did not open");
    return;
  }
  for (auto _ : state) {
    for (int k = 0; k < 96; ++k) {
      std::vector<double> levels(96, 0.0);
      levels[k] = 1.0;
      if (!dome.SetPattern({levels}).ok() || !camera.Trigger().ok() || !camera.WaitFrame(1000).ok()) {
        state.SkipWithError("capture failed");
        return;
      }
    }
  }
  (void)camera.Stop();
  (void)dome.Close();
}
BENCHMARK(BM_Capture96Lights)->Unit(benchmark::kMillisecond)->Iterations(1);

}  // namespace
}  // namespace photorig::sim

BENCHMARK_MAIN();
