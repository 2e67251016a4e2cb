// MERL evaluation throughput, filling a table from a model, and the time of
// one fit per model against the number of samples.

#include "photorig/solvers/brdf/fit.h"
#include "photorig/solvers/brdf/merl.h"

#include "synthetic_samples.h"

#include <benchmark/benchmark.h>

#include <random>

namespace {

using namespace photorig::solvers::brdf;

ModelParams Glossy(Model model) {
  ModelParams p;
  p.model = model;
  p.diffuse = {0.25, 0.15, 0.05};
  p.specular = model == Model::kGgx ? Eigen::Vector3d(0.9, 0.7, 0.5) : Eigen::Vector3d(0.4, 0.3, 0.2);
  p.shape = model == Model::kGgx ? 0.15 : 60.0;
  return p;
}

const MerlTable& Table() {
  static const MerlTable table =
      MerlTable::FromFunction([](const DirectionPair& d) { return Evaluate(Glossy(Model::kGgx), d.wi, d.wo); });
  return table;
}

void BM_MerlEvaluate(benchmark::State& state) {
  const MerlTable& table = Table();
  std::mt19937 rng(1);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<DirectionPair> pairs(4096);
  for (auto& p : pairs) {
    p.wi = Eigen::Vector3d(g(rng), g(rng), std::abs(g(rng))).normalized();
    p.wo = Eigen::Vector3d(g(rng), g(rng), std::abs(g(rng))).normalized();
  }
  for (auto _ : state)
    for (const auto& p : pairs) benchmark::DoNotOptimize(table.Evaluate(p.wi, p.wo));
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(pairs.size()));
}
BENCHMARK(BM_MerlEvaluate);

void BM_MerlTableFromModel(benchmark::State& state) {
  for (auto _ : state) {
    MerlTable table =
        MerlTable::FromFunction([](const DirectionPair& d) { return Evaluate(Glossy(Model::kGgx), d.wi, d.wo); });
    benchmark::DoNotOptimize(table.plane(0).data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(MerlTable::kCells));
  state.SetLabel("whole table, GGX");
}
BENCHMARK(BM_MerlTableFromModel)->Unit(benchmark::kMillisecond);

void BM_Fit(benchmark::State& state) {
  const auto model = static_cast<Model>(state.range(0));
  photorig::solvers::brdf::testing::SyntheticSpec spec;
  spec.count = static_cast<int>(state.range(1));
  const auto samples = photorig::solvers::brdf::testing::SyntheticSamples(
      Glossy(model == Model::kLambertian ? Model::kGgx : model), spec);
  for (auto _ : state) benchmark::DoNotOptimize(FitModel(model, samples).cost);
  state.SetItemsProcessed(state.iterations() * spec.count);
  state.SetLabel(ModelName(model));
}
BENCHMARK(BM_Fit)
    ->ArgsProduct({{static_cast<int>(Model::kLambertian), static_cast<int>(Model::kBlinnPhong),
                    static_cast<int>(Model::kGgx)},
                   {100, 1000, 10000}})
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
