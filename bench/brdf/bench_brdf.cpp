// MERL evaluation throughput, filling a table from a model, the time of one
// fit per model against the number of samples, and fitting a whole MERL table:
// FitModel (a subsample, then every cell for the cost) against the same GGX
// least squares over every cell solved by Ceres and by a Levenberg-Marquardt
// on photorig_autodiff's dual numbers, from the same start; the choice among
// six models, and FitTable as `photorig brdf fit TABLE` runs it.

#include "lobes.h"
#include "photorig/solvers/autodiff/dual.h"
#include "photorig/solvers/brdf/fit.h"
#include "photorig/solvers/brdf/measured.h"
#include "photorig/solvers/brdf/merl.h"
#include "photorig/solvers/brdf/table_fit.h"

#include "synthetic_samples.h"

#include <benchmark/benchmark.h>
#include <ceres/ceres.h>
#include <Eigen/Cholesky>

#include <algorithm>
#include <memory>
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

// ---- A whole MERL table ---------------------------------------------------

// GGX as Ngan et al. fit the MERL paints: a glossy coloured metal-like lobe.
ModelParams TableTruth() {
  ModelParams p;
  p.model = Model::kGgx;
  p.diffuse = {0.2, 0.15, 0.1};
  p.specular = {0.9, 0.8, 0.6};
  p.shape = 0.25;
  return p;
}

// A MERL table filled from TableTruth, each cell's value with 2 % Gaussian
// noise (a noise-free table would be fitted exactly from any subset), as
// `photorig brdf fit TABLE` reads one.
const MeasuredBrdf& NoisyTable() {
  static const MeasuredBrdf brdf = [] {
    std::mt19937 rng(7);
    std::normal_distribution<double> noise(0.0, 0.02);
    const auto table = std::make_shared<MerlTable>(MerlTable::FromFunction([&](const DirectionPair& d) {
      Eigen::Vector3d f = Evaluate(TableTruth(), d.wi, d.wo);
      for (int c = 0; c < 3; ++c) f[c] *= 1.0 + noise(rng);
      return std::optional<Eigen::Vector3d>(f);
    }));
    return MeasuredBrdf(MerlBrdf{table});  // as ReadMeasured gives it
  }();
  return brdf;
}

// Every cell of NoisyTable whose directions lie within 80 deg of the normal,
// as FitModel's samples.
const std::vector<BrdfSample>& WholeTable() {
  static const std::vector<BrdfSample> samples = [] {
    TableSampling cells;
    cells.theta_h_steps = MerlTable::kThetaHBins;
    cells.theta_d_steps = MerlTable::kThetaDBins;
    cells.phi_d_steps = MerlTable::kPhiDBins;
    return SampleMeasured(NoisyTable(), cells);
  }();
  return samples;
}

// The log loss of one cell under GGX, x = (rho_d x 3, F0 x 3, log a): the
// residuals FitModel's Ceres problem has, written once for both solvers.
struct CellResidual {
  Geometry g;
  Eigen::Vector3d value;
  template <typename T>
  bool operator()(const T* x, T* residual) const {
    using std::exp;
    using std::log;
    const T a = exp(x[6]);
    for (int c = 0; c < 3; ++c) {
      const T f = x[c] / M_PI + internal::Lobe(Model::kGgx, x[3 + c], a, T(0.0), g);
      residual[c] = log(1.0 + f * g.cos_i) - std::log(1.0 + value[c] * g.cos_i);
    }
    return true;
  }
};

std::vector<CellResidual> CellResiduals(const std::vector<BrdfSample>& samples) {
  std::vector<CellResidual> cells;
  cells.reserve(samples.size());
  for (const BrdfSample& s : samples) cells.push_back({GeometryOf(s.wi, s.wo), s.value});
  return cells;
}

// The same start for both solvers: 20 % off the truth in every parameter.
std::array<double, 7> Start() {
  const ModelParams t = TableTruth();
  return {1.2 * t.diffuse[0], 1.2 * t.diffuse[1], 1.2 * t.diffuse[2], 0.8 * t.specular[0],
          0.8 * t.specular[1], 0.8 * t.specular[2], std::log(1.2 * t.shape)};
}

// Ceres as FitModel runs it (DENSE_QR, bounds, one thread; default tolerances).
double SolveWithCeres(const std::vector<CellResidual>& cells, std::array<double, 7>* x, int* iterations) {
  ceres::Problem problem;
  for (const CellResidual& c : cells)
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<CellResidual, 3, 7>(new CellResidual(c)), nullptr,
                             x->data());
  for (int k = 0; k < 6; ++k) problem.SetParameterLowerBound(x->data(), k, 0.0);
  for (int k = 3; k < 6; ++k) problem.SetParameterUpperBound(x->data(), k, 1.0);
  problem.SetParameterLowerBound(x->data(), 6, std::log(0.005));
  problem.SetParameterUpperBound(x->data(), 6, 0.0);
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  *iterations = static_cast<int>(summary.iterations.size());
  return 2.0 * summary.final_cost;
}

// Levenberg-Marquardt on the normal equations: each iteration one pass over
// the cells with Dual<7> (forward mode, all seven derivatives at once)
// accumulating J^T J and J^T r, a damped 7x7 solve, the step clipped to the
// same bounds. Stops as Ceres' function tolerance does (relative cost change
// below 1e-6).
double SolveWithOwnLm(const std::vector<CellResidual>& cells, std::array<double, 7>* x_out, int* iterations) {
  using Dual7 = photorig::solvers::autodiff::Dual<7>;
  using Vector7 = Eigen::Matrix<double, 7, 1>;
  const Vector7 lower = (Vector7() << 0, 0, 0, 0, 0, 0, std::log(0.005)).finished();
  const Vector7 upper = (Vector7() << 1e300, 1e300, 1e300, 1, 1, 1, 0).finished();
  auto cost_of = [&](const Vector7& x) {
    double cost = 0.0, r[3];
    for (const CellResidual& c : cells) {
      c(x.data(), r);
      cost += r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
    }
    return cost;
  };
  Vector7 x = Eigen::Map<const Vector7>(x_out->data());
  double cost = cost_of(x), lambda = 1e-4;
  *iterations = 0;
  for (int it = 0; it < 50; ++it) {
    ++*iterations;
    Eigen::Matrix<double, 7, 7> jtj = Eigen::Matrix<double, 7, 7>::Zero();
    Vector7 jtr = Vector7::Zero();
    Dual7 xd[7], r[3];
    for (int k = 0; k < 7; ++k) xd[k] = Dual7(x[k], k);
    for (const CellResidual& c : cells) {
      c(xd, r);
      for (int ch = 0; ch < 3; ++ch) {
        jtj.selfadjointView<Eigen::Lower>().rankUpdate(r[ch].tangent);
        jtr += r[ch].value * r[ch].tangent;
      }
    }
    jtj = jtj.selfadjointView<Eigen::Lower>();
    bool improved = false;
    while (lambda < 1e12) {
      Eigen::Matrix<double, 7, 7> damped = jtj;
      damped.diagonal() += lambda * jtj.diagonal();
      const Vector7 trial = (x - damped.ldlt().solve(jtr)).cwiseMax(lower).cwiseMin(upper);
      const double trial_cost = cost_of(trial);
      if (trial_cost < cost) {
        const double change = (cost - trial_cost) / cost;
        x = trial;
        cost = trial_cost;
        lambda = std::max(lambda / 3.0, 1e-12);
        improved = change > 1e-6;
        break;
      }
      lambda *= 4.0;
    }
    if (!improved) break;
  }
  Eigen::Map<Vector7>(x_out->data()) = x;
  return cost;
}

// Whole table: the same least squares (every cell), same start, two solvers.
void BM_WholeTableGgx(benchmark::State& state) {
  const std::vector<CellResidual> cells = CellResiduals(WholeTable());
  const bool own = state.range(0) == 1;
  std::array<double, 7> x{};
  int iterations = 0;
  for (auto _ : state) {
    x = Start();
    benchmark::DoNotOptimize(own ? SolveWithOwnLm(cells, &x, &iterations) : SolveWithCeres(cells, &x, &iterations));
  }
  const ModelParams t = TableTruth();
  state.counters["cells"] = static_cast<double>(cells.size());
  state.counters["iterations"] = iterations;
  state.counters["a_rel_error"] = std::exp(x[6]) / t.shape - 1.0;
  state.counters["rho_d_rel_error"] = x[0] / t.diffuse[0] - 1.0;
  state.SetLabel(own ? "own Levenberg-Marquardt (autodiff Dual<7>)" : "Ceres (DENSE_QR)");
}
BENCHMARK(BM_WholeTableGgx)->Arg(0)->Arg(1)->Iterations(1)->Unit(benchmark::kMillisecond);

// FitModel on the whole table: the grid start, a subsample of
// `max_fit_samples` (0: every cell) for the least squares, every cell for the
// final cost, and the covariance.
void BM_FitModelWholeTable(benchmark::State& state) {
  const std::vector<BrdfSample>& samples = WholeTable();
  FitOptions options;
  options.loss = FitLoss::kLog;
  options.max_fit_samples = static_cast<std::size_t>(state.range(0));
  FitSummary fit;
  for (auto _ : state) fit = FitModel(Model::kGgx, samples, options);
  const ModelParams t = TableTruth();
  state.counters["cells"] = static_cast<double>(samples.size());
  state.counters["a_rel_error"] = fit.params.shape / t.shape - 1.0;
  state.counters["rho_d_rel_error"] = fit.params.diffuse[0] / t.diffuse[0] - 1.0;
  state.counters["F0_rel_error"] = fit.params.specular[0] / t.specular[0] - 1.0;
  state.SetLabel("GGX, max_fit_samples " + std::to_string(state.range(0)));
}
BENCHMARK(BM_FitModelWholeTable)->Arg(5000)->Arg(20000)->Arg(0)->Iterations(1)->Unit(benchmark::kMillisecond);

// The whole choice on the whole table: six candidates, each fitted to all
// samples and to 5 held-out folds (36 fits), as `photorig brdf fit` does.
// Arg: SelectionOptions::fold_fit_samples (0: the folds see as many samples
// as the fits to all, FitOptions::max_fit_samples). ho_<model> is the
// candidate's held-out RMS, what the smaller folds could change.
void BM_SelectModelWholeTable(benchmark::State& state) {
  const std::vector<BrdfSample>& samples = WholeTable();
  SelectionOptions options;
  options.fit.loss = FitLoss::kLog;
  options.fold_fit_samples = static_cast<std::size_t>(state.range(0));
  SelectionSummary selection;
  for (auto _ : state) selection = SelectModel(samples, options);
  state.counters["cells"] = static_cast<double>(samples.size());
  state.counters["chose_ggx"] = selection.chosen == Model::kGgx ? 1.0 : 0.0;
  for (const FitSummary& fit : selection.candidates) {
    state.counters[std::string("ms_") + ModelName(fit.params.model)] = fit.total_ms;
    state.counters[std::string("it_") + ModelName(fit.params.model)] = fit.iterations;
    state.counters[std::string("ho_") + ModelName(fit.params.model)] = fit.held_out_rms;
  }
  state.SetLabel("six candidates, 5 folds");
}
BENCHMARK(BM_SelectModelWholeTable)->Arg(0)->Arg(5000)->Iterations(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// `photorig brdf fit TABLE` on NoisyTable: FitTable with its defaults (two
// draws of 20,000 cells, the six candidates, 5 held-out folds on the last
// draw, the passes over all cells). Wall time on the machine's cores.
void BM_FitTableWholeTable(benchmark::State& state) {
  TableFitSummary fit;
  for (auto _ : state) fit = FitTable(NoisyTable());
  const SelectionSummary& s = fit.selection;
  state.counters["cells"] = static_cast<double>(fit.cells);
  state.counters["chose_ggx"] = s.chosen == Model::kGgx ? 1.0 : 0.0;
  if (s.chosen == Model::kGgx) {
    const ModelParams& p = s.candidates[s.chosen_index].params;
    const ModelParams t = TableTruth();
    state.counters["a_rel_error"] = p.shape / t.shape - 1.0;
    state.counters["rho_d_rel_error"] = p.diffuse[0] / t.diffuse[0] - 1.0;
    state.counters["F0_rel_error"] = p.specular[0] / t.specular[0] - 1.0;
  }
  for (const FitSummary& f : s.candidates)
    state.counters[std::string("it_") + ModelName(f.params.model)] = f.iterations;
  state.SetLabel("FitTable, six candidates, two draws");
}
BENCHMARK(BM_FitTableWholeTable)->Iterations(1)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
