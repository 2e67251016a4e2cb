// Lambertian photometric stereo against the memory-bandwidth ceiling.
// BM_StreamingRead sums the same stack with the same threads: the fastest any
// solver that reads every sample once can be. The ratio of the two times is
// the figure recorded in docs/performance.md.

#include "photorig/solvers/ps/evaluation.h"
#include "photorig/solvers/ps/lambertian.h"
#include "photorig/solvers/ps/near_lights.h"
#include "photorig/solvers/ps/photometric_stereo.h"

#include <benchmark/benchmark.h>
#include <omp.h>

#include <Eigen/Dense>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <tuple>
#include <random>
#include <string>

namespace {

using photorig::solvers::ps::PhotometricStack;

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

// Sum of one plane chunk with 64 independent partial sums, so the loop is
// limited by memory rather than by the latency of one add chain; built for
// AVX-512/AVX2 as well, like the solver's kernels.
__attribute__((target_clones("avx512f", "avx2,fma", "default")))
float SumChunk(const float* data, int n) {
  alignas(64) float partial[64] = {};
  int p = 0;
  for (; p + 64 <= n; p += 64) {
#pragma omp simd
    for (int j = 0; j < 64; ++j) partial[j] += data[p + j];
  }
  float total = 0.0f;
  for (; p < n; ++p) total += data[p];
  for (float v : partial) total += v;
  return total;
}

void BM_StreamingRead(benchmark::State& state) {
  const PhotometricStack& stack = Stack(1024, 1024, static_cast<int>(state.range(0)), false);
  const int pixels = stack.width() * stack.height();
  const int lights = stack.light_count();
  for (auto _ : state) {
    float total = 0.0f;
    // One parallel region, as in the solver: each thread streams its half of every plane.
#pragma omp parallel reduction(+ : total)
    {
      const int threads = omp_get_num_threads(), thread = omp_get_thread_num();
      const int begin = static_cast<int>(static_cast<long>(pixels) * thread / threads);
      const int end = static_cast<int>(static_cast<long>(pixels) * (thread + 1) / threads);
      for (int k = 0; k < lights; ++k) total += SumChunk(stack.images[k].ptr<float>() + begin, end - begin);
    }
    benchmark::DoNotOptimize(total);
  }
  state.SetBytesProcessed(state.iterations() * static_cast<int64_t>(pixels) * stack.light_count() * 4);
}

// The L2 solve as one Eigen GEMM, x (P x 3) = I (P x K) * W^T (K x 3), on a
// contiguous copy of the stack (the solver's planes are separate images); no
// dark subtraction, residual or flags. The reference for what a library GEMM
// makes of the same memory traffic.
void BM_EigenGemm(benchmark::State& state) {
  const PhotometricStack& stack = Stack(1024, 1024, static_cast<int>(state.range(0)), false);
  const int pixels = stack.width() * stack.height();
  const int lights = stack.light_count();
  Eigen::MatrixXf samples(pixels, lights);
  for (int k = 0; k < lights; ++k)
    samples.col(k) = Eigen::Map<const Eigen::VectorXf>(stack.images[k].ptr<float>(), pixels);
  Eigen::MatrixXd a(lights, 3);
  for (int k = 0; k < lights; ++k) a.row(k) = stack.light_directions[k].transpose() / stack.light_scales[k];
  const Eigen::MatrixXf pinv_t = a.completeOrthogonalDecomposition().pseudoInverse().transpose().cast<float>();
  Eigen::MatrixXf x(pixels, 3);
  Eigen::setNbThreads(omp_get_max_threads());
  for (auto _ : state) {
    x.noalias() = samples * pinv_t;
    benchmark::DoNotOptimize(x.data());
  }
  state.SetBytesProcessed(state.iterations() * static_cast<int64_t>(pixels) * lights * 4);
}

void BM_Lambertian(benchmark::State& state) {
  const bool shadowed = state.range(1) != 0;
  const PhotometricStack& stack = Stack(1024, 1024, static_cast<int>(state.range(0)), shadowed);
  photorig::solvers::ps::LambertianOptions options;
  options.shadow_threshold = 0.5;
  options.exclude_unusable_samples = state.range(2) == 0;
  photorig::solvers::ps::NormalMap map;
  photorig::solvers::ps::SolverSummary summary;
  for (auto _ : state) {
    summary = photorig::solvers::ps::SolveLambertian(options, stack, &map);
    benchmark::DoNotOptimize(map.normals.data);
  }
  state.counters["subset_pixels"] = static_cast<double>(summary.pixels_on_light_subsets);
  state.SetBytesProcessed(state.iterations() * static_cast<int64_t>(stack.width()) * stack.height() *
                          stack.light_count() * 4);
}

// A sphere filling a square image under a 48-light dome (elevations 20-80
// deg), with read and shot noise; `shininess` > 0 adds a Blinn-Phong lobe of
// that exponent (rho_s = 0.3). Outside the sphere is masked out.
struct Scene {
  PhotometricStack stack;
  cv::Mat truth_normals;  // CV_32FC3
};

const Scene& Sphere(int size, double shininess) {
  static std::map<std::pair<int, double>, Scene> cache;
  auto found = cache.find({size, shininess});
  if (found != cache.end()) return found->second;
  PhotometricStack stack;
  const int lights = 48;
  std::mt19937 rng(2);
  std::normal_distribution<double> gauss(0.0, 1.0);
  stack.mask = cv::Mat::zeros(size, size, CV_8U);
  std::vector<Eigen::Vector3d> normals(static_cast<std::size_t>(size) * size, Eigen::Vector3d::Zero());
  for (int r = 0; r < size; ++r) {
    for (int c = 0; c < size; ++c) {
      const double x = (c + 0.5) / size * 2.0 - 1.0, y = 1.0 - (r + 0.5) / size * 2.0, rr = x * x + y * y;
      if (rr >= 0.95) continue;
      normals[r * size + c] = Eigen::Vector3d(x, y, std::sqrt(1.0 - rr));
      stack.mask.at<std::uint8_t>(r, c) = 255;
    }
  }
  const double read_sigma = 2.0, gain = 0.05, dark = 20.0;
  stack.noise = {read_sigma, gain};
  for (int k = 0; k < lights; ++k) {
    const double el = (20.0 + 60.0 * (k % 4) / 3.0) * M_PI / 180.0, az = 2 * M_PI * k / lights;
    const Eigen::Vector3d w(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
    const Eigen::Vector3d h = (w + Eigen::Vector3d::UnitZ()).normalized();
    stack.light_directions.push_back(w);
    stack.light_scales.push_back(3000.0);
    cv::Mat image(size, size, CV_32F);
    float* out = image.ptr<float>();
    for (std::size_t p = 0; p < normals.size(); ++p) {
      const double cos_light = std::max(0.0, normals[p].dot(w));
      double brdf = 0.6 / M_PI;
      if (shininess > 0.0) brdf += 0.3 * (shininess + 2.0) / (2.0 * M_PI) * std::pow(std::max(0.0, normals[p].dot(h)), shininess);
      const double signal = 3000.0 * brdf * cos_light;
      out[p] = static_cast<float>(dark + signal + std::sqrt(read_sigma * read_sigma + gain * signal) * gauss(rng));
    }
    stack.images.push_back(image);
  }
  stack.dark = cv::Mat(size, size, CV_32F, cv::Scalar(dark));
  cv::Mat truth(size, size, CV_32FC3);
  for (std::size_t p = 0; p < normals.size(); ++p)
    truth.ptr<cv::Vec3f>()[p] = cv::Vec3f(float(normals[p].x()), float(normals[p].y()), float(normals[p].z()));
  return cache.emplace(std::make_pair(size, shininess), Scene{std::move(stack), truth}).first->second;
}

// Every method on the same sphere, so `auto` / `l2` is a ratio within one run.
void BM_Method(benchmark::State& state) {
  const auto method = static_cast<photorig::solvers::ps::Method>(state.range(0));
  const Scene& scene = Sphere(384, static_cast<double>(state.range(1)));
  PhotometricStack stack = scene.stack;
  if (state.range(3) == 0) stack.noise.shot_gain = 0.0;  // estimated from the data by the methods that need it
  photorig::solvers::ps::PhotometricStereoOptions options;
  options.method = method;
  if (state.range(2) == 1) options.blinn_phong.fitter = photorig::solvers::ps::BlinnPhongOptions::Fitter::kPerPixel;
  options.lambertian.shadow_threshold = 6.0;  // 3 read-noise sigmas
  photorig::solvers::ps::NormalMap map;
  photorig::solvers::ps::SolverSummary summary;
  // Each step's time summed over the run's solves: one solve's figures move
  // by tens of percent on this scale.
  double setup_ms = 0.0, tiles_ms = 0.0, steps_5_6_ms = 0.0, step_7_ms = 0.0;
  for (auto _ : state) {
    summary = photorig::solvers::ps::SolvePhotometricStereo(options, stack, &map);
    benchmark::DoNotOptimize(map.normals.data);
    setup_ms += summary.setup_ms;
    tiles_ms += summary.tiles_ms;
    steps_5_6_ms += summary.shared_lobe_ms;
    step_7_ms += summary.low_frequency_ms;
  }
  state.SetLabel(std::string(photorig::solvers::ps::MethodName(method)) + (state.range(2) == 1 ? " per pixel" : "") +
                 (state.range(3) == 0 ? " noise estimated" : ""));
  const double solved = std::max<std::size_t>(1, summary.pixels_solved);
  state.counters["lambertian_pct"] = 100.0 * summary.pixels_lambertian / solved;
  state.counters["blinn_phong_pct"] = 100.0 * summary.pixels_blinn_phong / solved;
  state.counters["low_frequency_pct"] = 100.0 * summary.pixels_low_frequency / solved;
  state.counters["shared_lobe_pct"] = 100.0 * summary.pixels_shared_lobe / solved;  // `auto`'s step 5
  state.counters["mean_deg"] = photorig::solvers::ps::CompareNormals(map.normals, scene.truth_normals, stack.mask).mean_deg;
  // The steps' mean times (SolverSummary): where a method's time beyond `l2` goes.
  const auto mean = [&state](double sum_ms) {
    return benchmark::Counter(sum_ms / std::max<benchmark::IterationCount>(1, state.iterations()));
  };
  state.counters["setup_ms"] = mean(setup_ms);
  state.counters["tiles_ms"] = mean(tiles_ms);
  state.counters["steps_5_6_ms"] = mean(steps_5_6_ms);
  state.counters["step_7_ms"] = mean(step_7_ms);
}

// A method and `l2` timed alternately on the same sphere, each iteration a
// pair. The machine's speed drifts within seconds, so a ratio of two separate
// benchmarks can be off by tens of percent; the median of the paired ratios
// is not. The reported time is the method's own.
void BM_MethodVsL2(benchmark::State& state) {
  using Clock = std::chrono::steady_clock;
  const Scene& scene = Sphere(384, static_cast<double>(state.range(1)));
  photorig::solvers::ps::PhotometricStereoOptions options;
  options.method = static_cast<photorig::solvers::ps::Method>(state.range(0));
  options.lambertian.shadow_threshold = 6.0;  // as BM_Method
  photorig::solvers::ps::PhotometricStereoOptions l2 = options;
  l2.method = photorig::solvers::ps::Method::kL2;
  photorig::solvers::ps::NormalMap map, l2_map;
  std::vector<double> ratios;
  double fastest = std::numeric_limits<double>::infinity(), fastest_l2 = fastest;
  for (auto _ : state) {
    const auto start = Clock::now();
    photorig::solvers::ps::SolvePhotometricStereo(l2, scene.stack, &l2_map);
    const auto middle = Clock::now();
    photorig::solvers::ps::SolvePhotometricStereo(options, scene.stack, &map);
    const auto end = Clock::now();
    benchmark::DoNotOptimize(map.normals.data);
    benchmark::DoNotOptimize(l2_map.normals.data);
    const double l2_s = std::chrono::duration<double>(middle - start).count();
    const double method_s = std::chrono::duration<double>(end - middle).count();
    state.SetIterationTime(method_s);
    ratios.push_back(method_s / l2_s);
    fastest = std::min(fastest, method_s);
    fastest_l2 = std::min(fastest_l2, l2_s);
  }
  std::nth_element(ratios.begin(), ratios.begin() + ratios.size() / 2, ratios.end());
  state.counters["vs_l2_median"] = ratios[ratios.size() / 2];
  state.counters["vs_l2_fastest"] = fastest / fastest_l2;
  state.counters["l2_fastest_ms"] = 1e3 * fastest_l2;
  state.SetLabel(photorig::solvers::ps::MethodName(options.method));
}

// A 34 mm sphere filling a square image under the 48 LEDs of Sphere() moved
// to `dome_radius_mm`, each aimed at the origin (Lambertian emitters), with
// the same noise and, for a shininess above 0, Sphere()'s lobe seen from
// +z; the sphere's rim on the sample plane.
struct NearScene {
  Scene scene;
  std::vector<photorig::solvers::camera::NearLight> lights;
  double pixel_pitch_mm = 0.0;
};

const NearScene& NearSphere(int size, double dome_radius_mm, double shininess) {
  static std::map<std::tuple<int, double, double>, NearScene> cache;
  auto found = cache.find({size, dome_radius_mm, shininess});
  if (found != cache.end()) return found->second;
  constexpr double kRadiusMm = 17.0;
  NearScene near;
  near.pixel_pitch_mm = 2.0 * kRadiusMm / size;
  near.scene = Sphere(size, 0.0);  // its mask, truth, lights' directions and noise model
  PhotometricStack& stack = near.scene.stack;
  std::mt19937 rng(3);
  std::normal_distribution<double> gauss(0.0, 1.0);
  for (std::size_t k = 0; k < stack.light_directions.size(); ++k) {
    const Eigen::Vector3d w = stack.light_directions[k];
    near.lights.push_back({dome_radius_mm * w, -w, 1.0});
    // Its own pixels: the copied scene's images share their buffers with Sphere()'s cache.
    stack.images[k] = stack.images[k].clone();
    float* out = stack.images[k].ptr<float>();
    const cv::Vec3f* normal = near.scene.truth_normals.ptr<cv::Vec3f>();
    for (int p = 0; p < size * size; ++p) {
      if (!stack.mask.data[p]) continue;
      const Eigen::Vector3d n(normal[p][0], normal[p][1], normal[p][2]);
      const Eigen::Vector3d point = kRadiusMm * n;
      Eigen::Vector3d towards;
      const double irradiance = near.lights[k].RelativeIrradiance(point, &towards);
      double brdf = 0.6 / M_PI;
      if (shininess > 0.0)
        brdf += 0.3 * (shininess + 2.0) / (2.0 * M_PI) *
                std::pow(std::max(0.0, n.dot((towards + Eigen::Vector3d::UnitZ()).normalized())), shininess);
      const double signal = stack.light_scales[k] * brdf * std::max(0.0, n.dot(towards)) * irradiance;
      out[p] = static_cast<float>(20.0 + signal + std::sqrt(4.0 + 0.05 * signal) * gauss(rng));
    }
  }
  return cache.emplace(std::make_tuple(size, dome_radius_mm, shininess), std::move(near)).first->second;
}

// The near-light solve and the distant one (the same method) timed
// alternately on the same near-LED stack, each iteration a pair: the time
// the rounds of normals and depth cost over one distant solve, and what they
// buy in accuracy. The reported time is the near solve's normals, as the
// distant solve gives; with_surface_ms adds the full-resolution surface.
void BM_NearVsDistant(benchmark::State& state) {
  using Clock = std::chrono::steady_clock;
  const NearScene& near = NearSphere(384, static_cast<double>(state.range(0)), static_cast<double>(state.range(2)));
  photorig::solvers::ps::PhotometricStereoOptions options;
  options.method = static_cast<photorig::solvers::ps::Method>(state.range(1));
  options.lambertian.shadow_threshold = 6.0;  // as BM_Method
  photorig::solvers::ps::NearLightOptions near_options;
  near_options.camera = photorig::solvers::camera::Camera::Orthographic(384, 384, near.pixel_pitch_mm);
  photorig::solvers::ps::NormalMap map, distant_map;
  cv::Mat height;
  photorig::solvers::ps::NearLightSummary summary;
  std::vector<double> ratios;
  for (auto _ : state) {
    const auto start = Clock::now();
    photorig::solvers::ps::SolvePhotometricStereo(options, near.scene.stack, &distant_map);
    const auto middle = Clock::now();
    summary = photorig::solvers::ps::SolveNearLightPhotometricStereo(options, near_options, near.scene.stack, near.lights,
                                                                     &map, nullptr);
    const auto end = Clock::now();
    benchmark::DoNotOptimize(map.normals.data);
    const double distant_s = std::chrono::duration<double>(middle - start).count();
    const double near_s = std::chrono::duration<double>(end - middle).count();
    state.SetIterationTime(near_s);
    ratios.push_back(near_s / distant_s);
  }
  std::nth_element(ratios.begin(), ratios.begin() + ratios.size() / 2, ratios.end());
  state.counters["vs_distant_median"] = ratios[ratios.size() / 2];
  state.counters["with_surface_ms"] =
      photorig::solvers::ps::SolveNearLightPhotometricStereo(options, near_options, near.scene.stack, near.lights, &map,
                                                             &height)
          .solve_ms;
  state.counters["rounds"] = summary.rounds;
  state.counters["depth_pct"] = 100.0 * summary.depth_ms / std::max(1e-9, summary.solve_ms);
  const cv::Mat& truth = near.scene.truth_normals;
  state.counters["near_mean_deg"] = photorig::solvers::ps::CompareNormals(map.normals, truth, near.scene.stack.mask).mean_deg;
  state.counters["distant_mean_deg"] =
      photorig::solvers::ps::CompareNormals(distant_map.normals, truth, near.scene.stack.mask).mean_deg;
  state.SetLabel(photorig::solvers::ps::MethodName(options.method));
}

BENCHMARK(BM_StreamingRead)->Arg(96)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_EigenGemm)->Arg(96)->Unit(benchmark::kMillisecond)->UseRealTime();
// Args: lights, shadowed scene, plain L2 (every sample, as `--method l2`).
BENCHMARK(BM_Lambertian)
    ->ArgNames({"lights", "shadowed", "l2"})
    ->Args({96, 0, 1})
    ->Args({96, 0, 0})
    ->Args({96, 1, 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
// Args: method (l2, lambertian, robust, blinn-phong, auto, low-frequency as 0-5), Blinn-Phong
// exponent (0 = matte), fitter (0 lanes, 1 per pixel with forward-mode autodiff),
// noise model (1 given; 0 shot noise unknown, so estimated from the data first).
BENCHMARK(BM_Method)
    ->ArgNames({"method", "shininess", "per_pixel", "noise_known"})
    ->Args({0, 0, 0, 1})
    ->Args({1, 0, 0, 1})
    ->Args({4, 0, 0, 1})
    ->Args({4, 0, 0, 0})
    ->Args({0, 50, 0, 1})
    ->Args({2, 50, 0, 1})
    ->Args({3, 50, 0, 1})
    ->Args({4, 50, 0, 1})
    ->Args({4, 50, 0, 0})
    ->Args({4, 50, 1, 1})
    ->Args({5, 0, 0, 1})
    ->Args({5, 50, 0, 1})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
// Args: method (as above), Blinn-Phong exponent. The targets: `auto` within
// 1.5x of `l2` on the matte sphere and within 10x on the shiny one.
BENCHMARK(BM_MethodVsL2)
    ->ArgNames({"method", "shininess"})
    ->Args({1, 0})
    ->Args({4, 0})
    ->Args({4, 50})
    ->Args({5, 0})
    ->Args({5, 50})
    ->Unit(benchmark::kMillisecond)
    ->UseManualTime();
// Args: the LEDs' distance (mm), the method of both solves (as BM_Method's),
// the Blinn-Phong exponent (0 = matte). The target: near within 3x of distant.
BENCHMARK(BM_NearVsDistant)
    ->ArgNames({"dome_mm", "method", "shininess"})
    ->Args({80, 1, 0})
    ->Args({400, 1, 0})
    ->Args({80, 2, 0})
    ->Args({80, 2, 50})
    ->Args({80, 3, 50})
    ->Args({80, 4, 50})
    ->Args({80, 5, 50})
    ->Unit(benchmark::kMillisecond)
    ->UseManualTime();

}  // namespace

BENCHMARK_MAIN();
