// Tomography against the memory-bandwidth ceiling. A sparse projection reads
// each stored entry of W once (a float value and a 32-bit column index) plus
// the x it points at; BM_StreamingRead sums an array of the same size with the
// same threads, the fastest any product over W can be. The ratio of
// BM_SparseForward to BM_StreamingRead is the figure in docs/performance.md.
// BM_MatrixFree* trace the rays in every product (volumes whose W does not
// fit); BM_Iteration/<method> is one SIRT or CGLS iteration, or one ART or
// SART pass. BM_MatrixFreeSirt is one SIRT iteration on the large case
// (256^3 from 180 views of 256^2: W would take some 55 GB), matrix-free; its
// peak resident memory is the figure that says it fits.
//
// Problems: an n^3 volume seen by parallel views of n x n pixels: 90 views at
// n = 64, 20 at n = 128 (W and W^T then take about 1.2 GB), 180 at n = 256.

#include "photorig/solvers/tomography/projector.h"
#include "photorig/solvers/tomography/reconstruct.h"

#include <benchmark/benchmark.h>

#include <map>
#include <memory>
#include <numeric>

namespace {

namespace tomo = photorig::solvers::tomography;

struct Problem {
  tomo::VolumeGrid grid;
  tomo::Geometry geometry;
  std::unique_ptr<tomo::Projector> projector;
  Eigen::VectorXf x, b;
};

const Problem& Get(int n, tomo::Storage storage) {
  static std::map<std::pair<int, int>, std::unique_ptr<Problem>> cache;
  const int views = n <= 64 ? 90 : n <= 128 ? 20 : 180;
  auto& slot = cache[{n, static_cast<int>(storage)}];
  if (!slot) {
    slot = std::make_unique<Problem>();
    slot->grid = {n, n, n, 32.0 / n};
    slot->geometry.detector_cols = slot->geometry.detector_rows = n;
    slot->geometry.pixel_mm = 32.0 / n;
    slot->geometry.angles_rad = tomo::EvenAngles(views, 180.0);
    tomo::ProjectorOptions options;
    options.storage = storage;
    options.memory_budget_bytes = std::size_t{8} << 30;
    tomo::MakeProjector(slot->grid, slot->geometry, options, &slot->projector);
    slot->x = Eigen::VectorXf::Constant(slot->grid.voxels(), 0.01f);
    slot->projector->Forward(slot->x, &slot->b);
  }
  return *slot;
}

std::int64_t SparseBytes(const tomo::Projector& p) {
  return p.nonzeros() * static_cast<std::int64_t>(sizeof(float) + sizeof(std::int32_t));
}

void BM_StreamingRead(benchmark::State& state) {
  const Problem& p = Get(static_cast<int>(state.range(0)), tomo::Storage::kSparse);
  // As many bytes as W's values and indices.
  const std::vector<float> data(static_cast<std::size_t>(SparseBytes(*p.projector) / sizeof(float)), 1.0f);
  const auto size = static_cast<std::int64_t>(data.size());
  for (auto _ : state) {
    float sum = 0.0f;
    // simd: without it the sum is one dependency chain, slower than the memory.
#pragma omp parallel for simd reduction(+ : sum) schedule(static)
    for (std::int64_t i = 0; i < size; ++i) sum += data[static_cast<std::size_t>(i)];
    benchmark::DoNotOptimize(sum);
  }
  state.SetBytesProcessed(state.iterations() * SparseBytes(*p.projector));
}

void BM_SparseForward(benchmark::State& state) {
  const Problem& p = Get(static_cast<int>(state.range(0)), tomo::Storage::kSparse);
  Eigen::VectorXf y;
  for (auto _ : state) {
    p.projector->Forward(p.x, &y);
    benchmark::DoNotOptimize(y.data());
  }
  state.SetBytesProcessed(state.iterations() * SparseBytes(*p.projector));
  state.counters["rays_per_s"] = benchmark::Counter(static_cast<double>(p.projector->rays()) * state.iterations(),
                                                    benchmark::Counter::kIsRate);
}

void BM_SparseBack(benchmark::State& state) {
  const Problem& p = Get(static_cast<int>(state.range(0)), tomo::Storage::kSparse);
  Eigen::VectorXf x;
  for (auto _ : state) {
    p.projector->Back(p.b, &x);
    benchmark::DoNotOptimize(x.data());
  }
  state.SetBytesProcessed(state.iterations() * SparseBytes(*p.projector));
}

void BM_MatrixFreeForward(benchmark::State& state) {
  const Problem& p = Get(static_cast<int>(state.range(0)), tomo::Storage::kMatrixFree);
  Eigen::VectorXf y;
  for (auto _ : state) {
    p.projector->Forward(p.x, &y);
    benchmark::DoNotOptimize(y.data());
  }
  state.counters["rays_per_s"] = benchmark::Counter(static_cast<double>(p.projector->rays()) * state.iterations(),
                                                    benchmark::Counter::kIsRate);
}

void BM_MatrixFreeBack(benchmark::State& state) {
  const Problem& p = Get(static_cast<int>(state.range(0)), tomo::Storage::kMatrixFree);
  Eigen::VectorXf x;
  for (auto _ : state) {
    p.projector->Back(p.b, &x);
    benchmark::DoNotOptimize(x.data());
  }
  state.counters["rays_per_s"] = benchmark::Counter(static_cast<double>(p.projector->rays()) * state.iterations(),
                                                    benchmark::Counter::kIsRate);
}

void RunOneIteration(benchmark::State& state, tomo::Storage storage) {
  const Problem& p = Get(static_cast<int>(state.range(0)), storage);
  tomo::ReconstructOptions options;
  options.method = static_cast<tomo::Method>(state.range(1));
  options.stop_rule = tomo::StopRule::kIterations;
  options.max_iterations = 1;
  const tomo::Absorbance data{p.b, {}, {}};
  Eigen::VectorXf x;
  for (auto _ : state) {
    x.resize(0);
    const tomo::ReconstructionSummary s = tomo::Reconstruct(*p.projector, data, options, &x);
    // The setup (row and column sums) is one forward and one back projection:
    // time the iteration alone.
    state.SetIterationTime(s.solve_ms / 1e3);
  }
  state.SetLabel(tomo::MethodName(options.method));
}

void BM_Iteration(benchmark::State& state) { RunOneIteration(state, tomo::Storage::kSparse); }
void BM_MatrixFreeSirt(benchmark::State& state) { RunOneIteration(state, tomo::Storage::kMatrixFree); }

}  // namespace

BENCHMARK(BM_StreamingRead)->Arg(64)->Arg(128)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SparseForward)->Arg(64)->Arg(128)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SparseBack)->Arg(64)->Arg(128)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MatrixFreeForward)->Arg(64)->Arg(128)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MatrixFreeBack)->Arg(64)->Arg(128)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Iteration)
    ->ArgsProduct({{64, 128},
                   {static_cast<int>(tomo::Method::kArt), static_cast<int>(tomo::Method::kSirt),
                    static_cast<int>(tomo::Method::kCgls), static_cast<int>(tomo::Method::kSart)}})
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MatrixFreeSirt)
    ->Args({256, static_cast<int>(tomo::Method::kSirt)})
    ->UseManualTime()
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
