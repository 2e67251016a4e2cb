// Measures the data behind docs/charts/autodiff_*.png and writes it as CSV into a directory:
//
//   autodiff_timing_inputs.csv   seconds per gradient of a scalar loss with 1..1000 inputs
//   autodiff_timing_outputs.csv  seconds per Jacobian of a renderer with 6 inputs, 1..1000 outputs
//   autodiff_fd_accuracy.csv     max abs error of finite differences vs the step size
//
// Usage: photorig-autodiff-chart OUTPUT_DIR   (scripts/chart-autodiff.sh runs it, then plots)
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "photorig/solvers/autodiff/blinn_phong.h"
#include "photorig/solvers/autodiff/blinn_phong_jacobian.h"
#include "photorig/solvers/autodiff/blinn_phong_symbolic.h"
#include "photorig/solvers/autodiff/finite_difference.h"
#include "photorig/solvers/autodiff/jacobian.h"
#include "photorig/solvers/autodiff/random_pixel.h"
#include "photorig/solvers/autodiff/tape.h"

namespace photorig::solvers::autodiff {
namespace {

const std::vector<int> kSizes = {1, 2, 5, 10, 20, 50, 100, 200, 500, 1000};

// Best of five batches, each at least 2 ms long: the minimum shrugs off interference from other
// work on the machine, the batch length the clock's resolution.
double SecondsPerCall(const std::function<void()>& call) {
  using Clock = std::chrono::steady_clock;
  constexpr double kMinBatchSeconds = 2e-3;
  call();  // Warm-up: caches, tape growth.
  const auto time_batch = [&call](long calls) {
    const Clock::time_point start = Clock::now();
    for (long i = 0; i < calls; ++i) {
      call();
    }
    return std::chrono::duration<double>(Clock::now() - start).count();
  };
  long calls = 1;
  double seconds = time_batch(calls);
  while (seconds < kMinBatchSeconds) {
    calls *= 2;
    seconds = time_batch(calls);
  }
  double best = seconds / static_cast<double>(calls);
  for (int batch = 1; batch < 5; ++batch) {
    best = std::min(best, time_batch(calls) / static_cast<double>(calls));
  }
  return best;
}

// The inputs family: loss(L) = sum_i (L_i s_i - observed_i)^2 where the inputs L are the
// intensities of N lights and s_i is the Blinn-Phong shading of light i, rendered at every
// evaluation from a fixed normal and material. N inputs, one output.
class IntensityLoss {
 public:
  explicit IntensityLoss(const RandomPixel& random)
      : pixel_(random.pixel),
        normal_(Eigen::Vector3d(random.parameters[0], random.parameters[1], random.parameters[2])
                    .normalized()),
        lobe_(random.parameters[BlinnPhongPixel::kDiffuseAlbedo],
              random.parameters[BlinnPhongPixel::kSpecularAlbedo],
              random.parameters[BlinnPhongPixel::kExponent]) {}

  int num_inputs() const { return pixel_.num_lights(); }
  int num_outputs() const { return 1; }

  template <typename T>
  bool operator()(const T* intensities, T* loss) const {
    T sum(0.0);
    for (int i = 0; i < pixel_.num_lights(); ++i) {
      const T residual = intensities[i] * Shading(i) - pixel_.observed_intensity(i);
      sum += residual * residual;
    }
    loss[0] = sum;
    return true;
  }

  // Hand-derived: d loss / d L_i = 2 r_i s_i.
  void SymbolicGradient(const double* intensities, Eigen::VectorXd* gradient) const {
    gradient->resize(pixel_.num_lights());
    for (int i = 0; i < pixel_.num_lights(); ++i) {
      const double shading = Shading(i);
      (*gradient)[i] = 2.0 * (intensities[i] * shading - pixel_.observed_intensity(i)) * shading;
    }
  }

 private:
  double Shading(int i) const {
    return BlinnPhongShading<double>(normal_, lobe_, pixel_.light_direction(i),
                                     pixel_.half_vector(i));
  }

  const BlinnPhongPixel& pixel_;
  Eigen::Vector3d normal_;
  BlinnPhongLobe<double> lobe_;
};

struct Row {
  std::string method;
  double x;
  double y;
};

bool WriteCsv(const std::string& path, const char* header, const std::vector<Row>& rows) {
  std::ofstream out(path);
  out << header << '\n';
  out.precision(6);
  for (const Row& row : rows) {
    out << row.method << ',' << row.x << ',' << row.y << '\n';
  }
  out.close();
  if (!out) {
    std::fprintf(stderr, "cannot write %s\n", path.c_str());
    return false;
  }
  std::printf("wrote %s (%zu rows)\n", path.c_str(), rows.size());
  return true;
}

std::vector<double> Intensities(const BlinnPhongPixel& pixel) {
  std::vector<double> intensities(pixel.num_lights());
  for (int i = 0; i < pixel.num_lights(); ++i) {
    intensities[i] = pixel.light_intensity(i);
  }
  return intensities;
}

// A timing table and what its calls reuse: a tape and the value and Jacobian
// buffers.
struct Timings {
  std::vector<Row> rows;
  Tape tape;
  Eigen::VectorXd value;
  Eigen::MatrixXd jacobian;
  // Adds the row of `method` at size `size`: seconds per call of `call`.
  void Time(const char* method, int size, const std::function<void()>& call) {
    rows.push_back({method, static_cast<double>(size), SecondsPerCall(call)});
  }
};

std::vector<Row> TimeInputs() {
  Timings t;
  std::mt19937 rng(1);
  Eigen::VectorXd gradient;
  for (const int n : kSizes) {
    const RandomPixel random = MakeRandomPixel(n, rng);
    const IntensityLoss f(random);
    const std::vector<double> x = Intensities(random.pixel);
    t.value.resize(1);
    t.Time("evaluation", n, [&] { f(x.data(), t.value.data()); });
    t.Time("forward Dual<8>", n, [&] { ForwardJacobian<8>(f, x.data(), &t.value, &t.jacobian); });
    t.Time("forward DynamicDual", n, [&] { ForwardJacobian<kDynamic>(f, x.data(), &t.value, &t.jacobian); });
    t.Time("reverse", n, [&] { ReverseJacobian(f, x.data(), &t.tape, &t.value, &t.jacobian); });
    t.Time("forward difference", n, [&] {
      FiniteDifferenceJacobian(f, x.data(), {.scheme = DifferenceScheme::kForward}, &t.value,
                               &t.jacobian);
    });
    t.Time("central difference", n,
           [&] { FiniteDifferenceJacobian(f, x.data(), {}, &t.value, &t.jacobian); });
    t.Time("symbolic", n, [&] { f.SymbolicGradient(x.data(), &gradient); });
    std::printf("inputs %4d done\n", n);
  }
  return t.rows;
}

std::vector<Row> TimeOutputs() {
  Timings t;
  std::mt19937 rng(2);
  for (const int m : kSizes) {
    const RandomPixel random = MakeRandomPixel(m, rng);
    const BlinnPhongPixel& f = random.pixel;
    const double* x = random.parameters.data();
    t.value.resize(m);
    t.Time("evaluation", m, [&] { f(x, t.value.data()); });
    t.Time("forward Dual<6>", m,
           [&] { ForwardJacobian<BlinnPhongPixel::kNumParameters>(f, x, &t.value, &t.jacobian); });
    t.Time("reverse", m, [&] { ReverseJacobian(f, x, &t.tape, &t.value, &t.jacobian); });
    t.Time("forward difference", m, [&] {
      FiniteDifferenceJacobian(f, x, {.scheme = DifferenceScheme::kForward}, &t.value, &t.jacobian);
    });
    t.Time("central difference", m, [&] { FiniteDifferenceJacobian(f, x, {}, &t.value, &t.jacobian); });
    t.Time("symbolic", m, [&] { SymbolicBlinnPhongJacobian(f, x, &t.value, &t.jacobian); });
    std::printf("outputs %4d done\n", m);
  }
  return t.rows;
}

// True when no light of the pixel is within `margin` of a kink of the model (cos = 0 at
// grazing, or the specular clamp of a lit light), so that finite-difference steps up to ~margin
// measure truncation and rounding rather than a jump in the derivative.
bool FarFromKinks(const RandomPixel& random, double margin) {
  const Eigen::Vector3d n =
      Eigen::Vector3d(random.parameters[0], random.parameters[1], random.parameters[2])
          .normalized();
  for (int i = 0; i < random.pixel.num_lights(); ++i) {
    const double cos_light = random.pixel.light_direction(i).dot(n);
    const double cos_half = random.pixel.half_vector(i).dot(n);
    if (std::abs(cos_light) < margin || (cos_light > 0.0 && cos_half < margin)) {
      return false;
    }
  }
  return true;
}

// Max abs error against the symbolic Jacobian over 20 random pixels of 16 lights (away from the
// kinks), for finite differences at relative steps 1e-16 .. 1e-1 and, as a floor, for forward
// and reverse mode.
std::vector<Row> MeasureAccuracy() {
  std::vector<RandomPixel> pixels;
  std::mt19937 rng(3);
  while (pixels.size() < 20) {
    RandomPixel candidate = MakeRandomPixel(16, rng);
    if (FarFromKinks(candidate, 0.1)) {
      pixels.push_back(std::move(candidate));
    }
  }
  std::vector<Eigen::MatrixXd> references;
  Eigen::VectorXd value;
  Eigen::MatrixXd jacobian;
  for (const RandomPixel& p : pixels) {
    SymbolicBlinnPhongJacobian(p.pixel, p.parameters.data(), &value, &jacobian);
    references.push_back(jacobian);
  }
  const auto max_error = [&](const std::function<void(const RandomPixel&)>& differentiate) {
    double worst = 0.0;
    for (std::size_t k = 0; k < pixels.size(); ++k) {
      differentiate(pixels[k]);
      worst = std::max(worst, (jacobian - references[k]).cwiseAbs().maxCoeff());
    }
    return worst;
  };

  std::vector<Row> rows;
  for (int quarter_decade = -64; quarter_decade <= -4; ++quarter_decade) {
    const double step = std::pow(10.0, quarter_decade / 4.0);
    for (const auto& [name, scheme] :
         {std::pair{"forward difference", DifferenceScheme::kForward},
          std::pair{"central difference", DifferenceScheme::kCentral}}) {
      rows.push_back({name, step, max_error([&](const RandomPixel& p) {
                        FiniteDifferenceJacobian(p.pixel, p.parameters.data(),
                                                 {.scheme = scheme, .relative_step = step}, &value,
                                                 &jacobian);
                      })});
    }
  }
  // The default steps, marked on the chart.
  for (const auto& [name, scheme] :
       {std::pair{"forward difference default", DifferenceScheme::kForward},
        std::pair{"central difference default", DifferenceScheme::kCentral}}) {
    rows.push_back({name, DefaultRelativeStep(scheme), max_error([&](const RandomPixel& p) {
                      FiniteDifferenceJacobian(p.pixel, p.parameters.data(), {.scheme = scheme},
                                               &value, &jacobian);
                    })});
  }
  Tape tape;
  rows.push_back({"forward mode", 0.0, max_error([&](const RandomPixel& p) {
                    ForwardJacobian<BlinnPhongPixel::kNumParameters>(p.pixel, p.parameters.data(),
                                                                     &value, &jacobian);
                  })});
  rows.push_back({"reverse mode", 0.0, max_error([&](const RandomPixel& p) {
                    ReverseJacobian(p.pixel, p.parameters.data(), &tape, &value, &jacobian);
                  })});
  return rows;
}

}  // namespace
}  // namespace photorig::solvers::autodiff

int main(int argc, char** argv) {
  using namespace photorig::solvers::autodiff;
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUTPUT_DIR\n", argv[0]);
    return 2;
  }
  const std::string dir = argv[1];
  const bool ok =
      WriteCsv(dir + "/autodiff_fd_accuracy.csv", "method,relative_step,max_abs_error",
               MeasureAccuracy()) &&
      WriteCsv(dir + "/autodiff_timing_inputs.csv", "method,num_inputs,seconds", TimeInputs()) &&
      WriteCsv(dir + "/autodiff_timing_outputs.csv", "method,num_outputs,seconds", TimeOutputs());
  return ok ? 0 : 1;
}
