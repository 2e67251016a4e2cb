// Cost of a gradient of the Blinn-Phong least-squares loss of one pixel,
//   loss(n, rho_d, rho_s, e) = sum over lights of (I_i - observed_i)^2,
// by every method, next to one plain double evaluation of the same loss. Forward mode runs the
// same templated code with photorig's Dual<6> and with ceres::Jet<double, 6>. After the
// benchmarks, the ratios of their fastest CPU times in this one run are printed.
#include <algorithm>
#include <array>
#include <cstdio>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <ceres/jet.h>
#include <Eigen/Core>

#include "photorig/solvers/autodiff/blinn_phong.h"
#include "photorig/solvers/autodiff/blinn_phong_symbolic.h"
#include "photorig/solvers/autodiff/dual.h"
#include "photorig/solvers/autodiff/finite_difference.h"
#include "photorig/solvers/autodiff/ggx.h"
#include "photorig/solvers/autodiff/random_pixel.h"
#include "photorig/solvers/autodiff/tape.h"

namespace photorig::solvers::autodiff {
namespace {

constexpr int kNumParameters = BlinnPhongPixel::kNumParameters;
using Gradient = std::array<double, kNumParameters>;
using Jet = ceres::Jet<double, kNumParameters>;

RandomPixel BenchPixel(int num_lights) {
  std::mt19937 rng(1234);
  return MakeRandomPixel(num_lights, rng);
}

// The loss every method differentiates; `residuals` is caller-owned scratch of num_lights.
template <typename T>
T SquaredResidualSum(const BlinnPhongPixel& pixel, const T* parameters, T* residuals) {
  pixel(parameters, residuals);
  T sum(0.0);
  for (int i = 0; i < pixel.num_lights(); ++i) {
    sum += residuals[i] * residuals[i];
  }
  return sum;
}

// The loss as a DifferentiableFunction, for finite differences.
struct PixelLoss {
  const BlinnPhongPixel& pixel;
  int num_inputs() const { return kNumParameters; }
  int num_outputs() const { return 1; }
  bool operator()(const double* parameters, double* loss) const {
    std::vector<double> residuals(pixel.num_lights());
    loss[0] = SquaredResidualSum(pixel, parameters, residuals.data());
    return true;
  }
};

void PlainLoss(benchmark::State& state, int num_lights) {
  const RandomPixel random = BenchPixel(num_lights);
  Gradient x = random.parameters;
  std::vector<double> residuals(random.pixel.num_lights());
  for (auto _ : state) {
    benchmark::DoNotOptimize(x.data());
    double loss = SquaredResidualSum(random.pixel, x.data(), residuals.data());
    benchmark::DoNotOptimize(loss);
  }
}

const Dual<kNumParameters>::Tangent& TangentOf(const Dual<kNumParameters>& x) { return x.tangent; }
const Eigen::Matrix<double, kNumParameters, 1>& TangentOf(const Jet& x) { return x.v; }

template <typename Scalar>
void ForwardGradient(benchmark::State& state, int num_lights) {
  const RandomPixel random = BenchPixel(num_lights);
  Gradient x = random.parameters;
  std::array<Scalar, kNumParameters> seeded;
  std::vector<Scalar> residuals(random.pixel.num_lights());
  Gradient gradient;
  for (auto _ : state) {
    benchmark::DoNotOptimize(x.data());
    for (int j = 0; j < kNumParameters; ++j) {
      seeded[j] = Scalar(x[j], j);
    }
    const Scalar loss = SquaredResidualSum(random.pixel, seeded.data(), residuals.data());
    for (int j = 0; j < kNumParameters; ++j) {
      gradient[j] = TangentOf(loss)[j];
    }
    benchmark::DoNotOptimize(gradient.data());
  }
}

void ReverseGradient(benchmark::State& state, int num_lights) {
  const RandomPixel random = BenchPixel(num_lights);
  Gradient x = random.parameters;
  Tape tape;
  std::array<Var, kNumParameters> inputs;
  std::vector<Var> residuals(random.pixel.num_lights());
  Gradient gradient;
  for (auto _ : state) {
    benchmark::DoNotOptimize(x.data());
    tape.Reset();
    for (int j = 0; j < kNumParameters; ++j) {
      inputs[j] = tape.Variable(x[j]);
    }
    const Var loss = SquaredResidualSum(random.pixel, inputs.data(), residuals.data());
    tape.Backward(loss);
    for (int j = 0; j < kNumParameters; ++j) {
      gradient[j] = tape.Adjoint(inputs[j]);
    }
    benchmark::DoNotOptimize(gradient.data());
  }
  state.counters["tape_nodes"] = static_cast<double>(tape.size());
}

// gradient = 2 J^T r from the hand-derived Jacobian.
void SymbolicGradient(benchmark::State& state, int num_lights) {
  const RandomPixel random = BenchPixel(num_lights);
  Gradient x = random.parameters;
  Eigen::VectorXd residuals;
  Eigen::MatrixXd jacobian;
  Eigen::Matrix<double, kNumParameters, 1> gradient;
  for (auto _ : state) {
    benchmark::DoNotOptimize(x.data());
    SymbolicBlinnPhongJacobian(random.pixel, x.data(), &residuals, &jacobian);
    gradient.noalias() = 2.0 * jacobian.transpose() * residuals;
    benchmark::DoNotOptimize(gradient.data());
  }
}

void CentralDifferenceGradient(benchmark::State& state, int num_lights) {
  const RandomPixel random = BenchPixel(num_lights);
  const PixelLoss loss{random.pixel};
  Gradient x = random.parameters;
  Eigen::VectorXd value;
  Eigen::MatrixXd gradient;
  for (auto _ : state) {
    benchmark::DoNotOptimize(x.data());
    FiniteDifferenceJacobian(loss, x.data(), {}, &value, &gradient);
    benchmark::DoNotOptimize(gradient.data());
  }
}

// Each benchmark runs kRepetitions times and reports the fastest: interference from other work
// on a shared machine only ever adds time, so the minimum is the most repeatable estimate.
constexpr int kRepetitions = 5;

double Fastest(const std::vector<double>& times) {
  return *std::min_element(times.begin(), times.end());
}

// Collects the fastest CPU time of every benchmark, from the "min" aggregate when present, else
// from the iteration runs seen (e.g. with --benchmark_repetitions=1).
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const Run& run : runs) {
      if (run.error_occurred) {
        continue;
      }
      if (run.run_type == Run::RT_Iteration) {
        iteration_ns_[run.run_name.function_name].push_back(run.GetAdjustedCPUTime());
      } else if (run.aggregate_name == "min") {
        fastest_ns_[run.run_name.function_name] = run.GetAdjustedCPUTime();
      }
    }
    ConsoleReporter::ReportRuns(runs);
  }

  // Fastest CPU time of `name`, or a negative number when it did not run (filtered out).
  double Fastest(const std::string& name) const {
    if (const auto it = fastest_ns_.find(name); it != fastest_ns_.end()) {
      return it->second;
    }
    const auto it = iteration_ns_.find(name);
    return it == iteration_ns_.end() ? -1.0 : photorig::solvers::autodiff::Fastest(it->second);
  }

 private:
  std::map<std::string, std::vector<double>> iteration_ns_;
  std::map<std::string, double> fastest_ns_;
};

void PrintRatio(const RatioReporter& reporter, const char* label, const std::string& numerator,
                const std::string& denominator, const char* target) {
  const double a = reporter.Fastest(numerator);
  const double b = reporter.Fastest(denominator);
  if (a < 0.0 || b < 0.0) {
    return;
  }
  std::printf("  %-44s %6.2f   %s\n", label, a / b, target);
}

// The GGX pixel of the same lights and observations, and where to evaluate it
// (the Blinn-Phong exponent's place holds a roughness of 0.2).
struct BenchGgx {
  GgxPixel pixel;
  std::array<double, GgxPixel::kNumParameters> parameters;
};
BenchGgx MakeBenchGgx(int num_lights) {
  const RandomPixel random = BenchPixel(num_lights);
  Eigen::Matrix<double, Eigen::Dynamic, 3> lights(num_lights, 3);
  Eigen::VectorXd intensities(num_lights), observed(num_lights);
  for (int i = 0; i < num_lights; ++i) {
    lights.row(i) = random.pixel.light_direction(i).transpose();
    intensities[i] = random.pixel.light_intensity(i);
    observed[i] = random.pixel.observed_intensity(i);
  }
  BenchGgx ggx{GgxPixel(lights, intensities, Eigen::Vector3d::UnitZ(), observed), random.parameters};
  ggx.parameters[GgxPixel::kRoughness] = 0.2;
  return ggx;
}

// Residuals and Jacobian of a GGX pixel, as its fit (step 6 of `auto`) asks for them each iteration.
void GgxJacobian(benchmark::State& state, int num_lights, DerivativeMethod method) {
  const BenchGgx ggx = MakeBenchGgx(num_lights);
  Eigen::VectorXd residuals;
  Eigen::MatrixXd jacobian;
  for (auto _ : state) {
    benchmark::DoNotOptimize(GgxResidualsAndJacobian(ggx.pixel, ggx.parameters.data(), method, &residuals, &jacobian));
    benchmark::DoNotOptimize(jacobian.data());
  }
}

void GgxResiduals(benchmark::State& state, int num_lights) {
  const BenchGgx ggx = MakeBenchGgx(num_lights);
  Eigen::VectorXd residuals(num_lights);
  for (auto _ : state) {
    benchmark::DoNotOptimize(ggx.pixel(ggx.parameters.data(), residuals.data()));
    benchmark::DoNotOptimize(residuals.data());
  }
}

}  // namespace
}  // namespace photorig::solvers::autodiff

int main(int argc, char** argv) {
  using namespace photorig::solvers::autodiff;
  const std::vector<int> light_counts = {16, 256};
  for (const int lights : light_counts) {
    const auto add = [lights](const std::string& name, auto function) {
      benchmark::RegisterBenchmark((name + "/" + std::to_string(lights)).c_str(), function, lights)
          ->Repetitions(kRepetitions)
          ->ComputeStatistics("min", Fastest)
          ->ReportAggregatesOnly(true);
    };
    add("loss/plain", PlainLoss);
    add("gradient/reverse", ReverseGradient);
    add("gradient/forward-dual", ForwardGradient<Dual<kNumParameters>>);
    add("gradient/forward-jet", ForwardGradient<Jet>);
    add("gradient/symbolic", SymbolicGradient);
    add("gradient/central-difference", CentralDifferenceGradient);
    add("ggx/residuals", GgxResiduals);
    add("ggx/jacobian-forward", [](benchmark::State& state, int n) { GgxJacobian(state, n, DerivativeMethod::kForward); });
    add("ggx/jacobian-symbolic", [](benchmark::State& state, int n) { GgxJacobian(state, n, DerivativeMethod::kSymbolic); });
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) {
    return 1;
  }
  RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);

  std::printf("\nRatios of the fastest CPU times in this run (lower is better):\n");
  for (const int lights : light_counts) {
    const auto name = [lights](const std::string& benchmark) {
      return benchmark + "/" + std::to_string(lights);
    };
    std::printf("%d lights:\n", lights);
    PrintRatio(reporter, "reverse gradient / plain loss", name("gradient/reverse"),
               name("loss/plain"), "(target <= 4)");
    PrintRatio(reporter, "forward Dual<6> / ceres::Jet<double,6>", name("gradient/forward-dual"),
               name("gradient/forward-jet"), "(target <= 1.2)");
    PrintRatio(reporter, "forward Dual<6> gradient / plain loss", name("gradient/forward-dual"),
               name("loss/plain"), "");
    PrintRatio(reporter, "symbolic gradient / plain loss", name("gradient/symbolic"),
               name("loss/plain"), "");
    PrintRatio(reporter, "central-difference gradient / plain loss",
               name("gradient/central-difference"), name("loss/plain"), "");
    PrintRatio(reporter, "GGX Jacobian, forward Dual<6> / residuals", name("ggx/jacobian-forward"),
               name("ggx/residuals"), "");
    PrintRatio(reporter, "GGX Jacobian, symbolic / residuals", name("ggx/jacobian-symbolic"), name("ggx/residuals"),
               "");
  }
  benchmark::Shutdown();
  return 0;
}
