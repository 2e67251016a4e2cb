// Normal integration on a sphere's disc, against the sphere's own depth:
// Poisson from scratch (the factorisation, or above 4,096 pixels the
// multigrid levels, then the solve), Poisson again on the same pixels with a
// workspace that kept them (how the near-light rounds call it), and
// Frankot-Chellappa. The disc is 0.9 of the image's side; the error counter
// is the RMS depth error in pixels after each depth's mean is removed.

#include "photorig/solvers/ps/integration.h"

#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <utility>

namespace {

using photorig::solvers::ps::IntegrateNormals;
using photorig::solvers::ps::IntegrationOptions;
using photorig::solvers::ps::IntegrationWorkspace;
using photorig::solvers::ps::Integrator;

struct Sphere {
  cv::Mat normals, mask, depth;  // depth: the truth, in pixels
};

const Sphere& SphereOfSide(int side) {
  static std::map<int, Sphere> cache;
  if (auto found = cache.find(side); found != cache.end()) return found->second;
  Sphere s;
  s.normals.create(side, side, CV_32FC3);
  s.mask = cv::Mat::zeros(side, side, CV_8U);
  s.depth = cv::Mat::zeros(side, side, CV_64F);
  const double radius = 0.5 * side, centre = 0.5 * (side - 1);
  for (int r = 0; r < side; ++r)
    for (int c = 0; c < side; ++c) {
      const double x = c - centre, y = centre - r;  // y up
      const double inside = radius * radius - x * x - y * y;
      if (x * x + y * y > 0.81 * radius * radius) {  // 0.9 of the radius: no grazing normals
        s.normals.at<cv::Vec3f>(r, c) = cv::Vec3f(NAN, NAN, NAN);
        continue;
      }
      const double z = std::sqrt(inside);
      s.normals.at<cv::Vec3f>(r, c) = cv::Vec3f(static_cast<float>(x / radius), static_cast<float>(y / radius),
                                                static_cast<float>(z / radius));
      s.mask.at<std::uint8_t>(r, c) = 255;
      s.depth.at<double>(r, c) = z;
    }
  return cache.emplace(side, std::move(s)).first->second;
}

double RmsErrorPx(const Sphere& sphere, const cv::Mat& depth) {
  double truth_mean = 0.0, mean = 0.0;
  int n = 0;
  for (int r = 0; r < depth.rows; ++r)
    for (int c = 0; c < depth.cols; ++c)
      if (sphere.mask.at<std::uint8_t>(r, c) && std::isfinite(depth.at<float>(r, c)))
        truth_mean += sphere.depth.at<double>(r, c), mean += depth.at<float>(r, c), ++n;
  truth_mean /= n, mean /= n;
  double sum = 0.0;
  for (int r = 0; r < depth.rows; ++r)
    for (int c = 0; c < depth.cols; ++c)
      if (sphere.mask.at<std::uint8_t>(r, c) && std::isfinite(depth.at<float>(r, c))) {
        const double e = (depth.at<float>(r, c) - mean) - (sphere.depth.at<double>(r, c) - truth_mean);
        sum += e * e;
      }
  return std::sqrt(sum / n);
}

// Args: side (px), integrator (0 Poisson, 1 Frankot-Chellappa), reuse (1: a
// workspace that has factored these pixels, or built their levels, already).
void BM_IntegrateNormals(benchmark::State& state) {
  const Sphere& sphere = SphereOfSide(static_cast<int>(state.range(0)));
  IntegrationOptions options;
  options.integrator = state.range(1) == 0 ? Integrator::kPoisson : Integrator::kFrankotChellappa;
  const bool reuse = state.range(2) != 0;
  IntegrationWorkspace workspace;
  cv::Mat depth;
  if (reuse) IntegrateNormals(options, sphere.normals, sphere.mask, &depth, &workspace);
  int iterations = 0;
  for (auto _ : state) {
    IntegrationWorkspace fresh;
    const auto summary = IntegrateNormals(options, sphere.normals, sphere.mask, &depth, reuse ? &workspace : &fresh);
    if (!summary.IsSolutionUsable()) state.SkipWithError(summary.message.c_str());
    iterations = summary.iterations;
  }
  state.counters["unknowns"] = cv::countNonZero(sphere.mask);
  state.counters["iterations"] = iterations;  // Poisson by multigrid-preconditioned CG; 0: factored
  state.counters["rms_error_px"] = RmsErrorPx(sphere, depth);
  state.SetLabel(std::string(options.integrator == Integrator::kPoisson ? "poisson" : "frankot-chellappa") +
                 (reuse ? ", workspace kept" : ""));
}

}  // namespace

// 32: the near-light rounds' lattice; 384: the benchmark spheres; 1024: a 1 MP capture.
BENCHMARK(BM_IntegrateNormals)
    ->ArgNames({"side", "integrator", "reuse"})
    ->ArgsProduct({{32, 384, 1024}, {0}, {0, 1}})
    ->ArgsProduct({{32, 384, 1024}, {1}, {0}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
