// Lambertian photometric stereo against the memory-bandwidth ceiling.
// BM_StreamingRead sums the same stack with the same threads: the fastest any
// solver that reads every sample once can be. The ratio of the two times is
// the figure recorded in docs/performance.md.

#include "photorig/ps/lambertian.h"

#include <benchmark/benchmark.h>
#include <omp.h>

#include <cmath>
#include <random>

namespace {

using photorig::ps::PhotometricStack;

// A tilted-plane scene: every sample lit (the all-lights fast path), or, with
// `shadowed`, a sphere-like spread of normals so many pixels need their own subset.
const PhotometricStack& Stack(int width, int height, int lights, bool shadowed) {
  static std::map<std::tuple<int, int, int, bool>, PhotometricStack> cache;
  auto key = std::make_tuple(width, height, lights, shadowed);
  auto found = cache.find(key);
  if (found != cache.end()) return found->second;
  PhotometricStack stack;
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Eigen::Vector3d> normals(static_cast<std::size_t>(width) * height);
  const double max_tilt = shadowed ? 1.2 : 0.3;
  for (auto& n : normals) {
    const double tilt = max_tilt * std::sqrt(unit(rng)), az = 2 * M_PI * unit(rng);
    n = Eigen::Vector3d(std::sin(tilt) * std::cos(az), std::sin(tilt) * std::sin(az), std::cos(tilt));
  }
  for (int k = 0; k < lights; ++k) {
    const double el = (shadowed ? 0.4 : 1.1) + 0.4 * unit(rng), az = 2 * M_PI * k / lights;
    const Eigen::Vector3d w(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
    stack.light_directions.push_back(w);
    stack.light_scales.push_back(1000.0);
    cv::Mat image(height, width, CV_32F);
    float* out = image.ptr<float>();
    for (std::size_t p = 0; p < normals.size(); ++p)
      out[p] = static_cast<float>(10.0 + 1000.0 * 0.5 / M_PI * std::max(0.0, normals[p].dot(w)));
    stack.images.push_back(image);
  }
  stack.dark = cv::Mat(height, width, CV_32F, cv::Scalar(10.0));
  return cache.emplace(key, std::move(stack)).first->second;
}

void BM_StreamingRead(benchmark::State& state) {
  const PhotometricStack& stack = Stack(1024, 1024, static_cast<int>(state.range(0)), false);
  const int pixels = stack.width() * stack.height();
  const int lights = stack.light_count();
  for (auto _ : state) {
    float total = 0.0f;
    // One parallel region, as in the solver: each thread streams its share of every plane.
#pragma omp parallel reduction(+ : total)
    for (int k = 0; k < lights; ++k) {
      const float* data = stack.images[k].ptr<float>();
#pragma omp for simd schedule(static) nowait
      for (int p = 0; p < pixels; ++p) total += data[p];
    }
    benchmark::DoNotOptimize(total);
  }
  state.SetBytesProcessed(state.iterations() * static_cast<int64_t>(pixels) * stack.light_count() * 4);
}

void BM_Lambertian(benchmark::State& state) {
  const bool shadowed = state.range(1) != 0;
  const PhotometricStack& stack = Stack(1024, 1024, static_cast<int>(state.range(0)), shadowed);
  photorig::ps::LambertianOptions options;
  options.shadow_threshold = 0.5;
  photorig::ps::NormalMap map;
  photorig::ps::SolverSummary summary;
  for (auto _ : state) {
    summary = photorig::ps::SolveLambertian(options, stack, &map);
    benchmark::DoNotOptimize(map.normals.data);
  }
  state.counters["distinct_subsets"] = static_cast<double>(summary.distinct_light_subsets);
  state.SetBytesProcessed(state.iterations() * static_cast<int64_t>(stack.width()) * stack.height() *
                          stack.light_count() * 4);
}

BENCHMARK(BM_StreamingRead)->Arg(96)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Lambertian)->Args({96, 0})->Args({96, 1})->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
