// Inverse lighting and environment-map throughput on a 1024 x 1024 sphere;
// near LEDs placed from three chrome balls; one light's intensity from a white sphere.
#include "photorig/solvers/lighting/envmap.h"
#include "photorig/solvers/lighting/inverse_lighting.h"
#include "photorig/solvers/lighting/led_positions.h"
#include "photorig/solvers/lighting/light_intensity.h"
#include "photorig/solvers/lighting/relight.h"
#include "led_dome_scene.h"
#include "synthetic_sphere.h"

#include <benchmark/benchmark.h>

namespace {

using namespace photorig::solvers::lighting;

struct Scene {
  cv::Mat normals, mask, albedo, image;
  std::vector<Eigen::Vector3d> dome = testing::DomeDirections();
  std::vector<double> intensities = std::vector<double>(dome.size(), 1.0);
  Scene() {
    testing::SphereNormals(1024, 1.0, &normals, &mask);
    albedo = cv::Mat(normals.size(), CV_32F, cv::Scalar(0.7));
    Eigen::MatrixXd sh = Eigen::MatrixXd::Zero(9, 1);
    sh << 2.0, 0.4, 0.9, -0.3, 0.15, -0.1, 0.2, 0.12, -0.15;
    RenderShLighting(normals, albedo, sh, &image);
  }
};
const Scene& GetScene() {
  static const Scene scene;
  return scene;
}

void BM_ShFitFixedBand2(benchmark::State& state) {
  const Scene& s = GetScene();
  ShFitOptions options;
  options.selection = ShFitOptions::Selection::kFixed;
  options.fixed_band = 2;
  for (auto _ : state) benchmark::DoNotOptimize(FitShLighting(s.normals, s.albedo, s.image, s.mask, options));
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(s.normals.total()));
}
BENCHMARK(BM_ShFitFixedBand2)->Unit(benchmark::kMillisecond);

void BM_ShFitSelectedUpToBand4(benchmark::State& state) {
  const Scene& s = GetScene();
  for (auto _ : state) benchmark::DoNotOptimize(FitShLighting(s.normals, s.albedo, s.image, s.mask));
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(s.normals.total()));
}
BENCHMARK(BM_ShFitSelectedUpToBand4)->Unit(benchmark::kMillisecond);

// Arg: 1 drives the simplest LED set (LedWeightsOptions::simplest_led_set), 0 every LED NNLS drives.
void BM_LedWeightsNnls48(benchmark::State& state) {
  const Scene& s = GetScene();
  LedWeightsOptions options;
  options.simplest_led_set = state.range(0) != 0;
  LedWeightsSummary fit;
  for (auto _ : state) {
    fit = FitLedWeights(s.normals, s.albedo, s.image, s.mask, s.dome, s.intensities, options);
    benchmark::DoNotOptimize(fit.weights.data());
  }
  state.counters["active_leds"] = fit.active_leds;
  state.counters["leds_dropped"] = fit.leds_dropped;
  state.counters["relative_rms_residual"] = fit.relative_rms_residual;
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(s.normals.total()));
}
BENCHMARK(BM_LedWeightsNnls48)->ArgName("simplest")->Arg(1)->Arg(0)->Unit(benchmark::kMillisecond);

void BM_RenderShBand2(benchmark::State& state) {
  const Scene& s = GetScene();
  Eigen::MatrixXd sh = Eigen::MatrixXd::Zero(9, 3);
  sh.col(0).setConstant(0.5);
  cv::Mat image;
  for (auto _ : state) benchmark::DoNotOptimize(RenderShLighting(s.normals, s.albedo, sh, &image));
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(s.normals.total()));
}
BENCHMARK(BM_RenderShBand2)->Unit(benchmark::kMillisecond);

void BM_MirrorBallUnwrap1024(benchmark::State& state) {
  const cv::Mat ball(1024, 1024, CV_32FC3, cv::Scalar::all(1.0));
  const SphereGeometry sphere = LocateSphere(CameraModel{}, Circle{511.5, 511.5, 512.0});
  UnwrapOptions options;
  options.width = 1024;
  LatLongMap map;
  for (auto _ : state) benchmark::DoNotOptimize(MirrorBallToLatLong(ball, sphere, options, &map));
  state.SetItemsProcessed(state.iterations() * 1024 * 512);
}
BENCHMARK(BM_MirrorBallUnwrap1024)->Unit(benchmark::kMillisecond);

}  // namespace

// Twelve near LEDs placed from three 17 mm chrome balls, 384 x 384 frames:
// the balls found once, then per LED a highlight on each and the rays met.
void BM_LedPositions12(benchmark::State& state) {
  static const std::vector<cv::Mat> frames =
      testing::RenderLedFrames(false, testing::ThreeBalls(), testing::LedPositionsMm());
  const photorig::solvers::camera::Camera dome_camera = testing::DomeCamera(false);
  for (auto _ : state) benchmark::DoNotOptimize(EstimateLedPositions(frames, dome_camera, testing::ThreeBalls()));
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(frames.size()));
}
BENCHMARK(BM_LedPositions12)->Unit(benchmark::kMillisecond);

// One light's relative intensity from a 100 px white sphere (a 230 x 230
// 16-bit RGB frame, 31k samples): the fit, the adjacent-sample noise
// estimate and the model-error test.
void BM_LightIntensity100px(benchmark::State& state) {
  const testing::WhiteSphereScene scene = testing::MakeWhiteSphereScene(100.0, 230, 2.0, 1);
  const Eigen::Vector3d light = Eigen::Vector3d(0.4, 0.2, 0.89).normalized();
  cv::Mat frame;
  scene.Render(light, Eigen::Vector3d(3000, 2900, 2800)).convertTo(frame, CV_16UC3);
  LightIntensityEstimate estimate;
  for (auto _ : state) {
    estimate = EstimateIntensityFromSphere(frame, scene.geometry, light);
    benchmark::DoNotOptimize(estimate.rgb.data());
  }
  state.counters["samples"] = estimate.samples_used;
  state.counters["model_error"] = estimate.model_error;
}
BENCHMARK(BM_LightIntensity100px)->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
