// Fitting and applying colour models. The apply benchmark runs on a 1 MP
// 16-bit image; BM_MemoryPass converts the same image to float, the least any
// per-pixel colour transform must do, so the ratio says how far from
// bandwidth-bound the model evaluation is.

#include "chart_capture.h"
#include "photorig/solvers/color/apply.h"

#include <benchmark/benchmark.h>

namespace photorig::solvers::color {
namespace {

const ChartCalibration& Chart() {
  static const ChartCalibration chart = bench::SimulatedChart("nikon-5100", Illuminant::kD65, CalibrationOptions{});
  return chart;
}

const ModelSpec& SpecAt(int index) {
  static const std::vector<ModelSpec> specs = ModelSpec::All();
  return specs.at(static_cast<std::size_t>(index));
}

cv::Mat MegapixelImage() {
  cv::Mat image(1000, 1000, CV_16UC3);
  cv::randu(image, cv::Scalar::all(64), cv::Scalar::all(3800));
  return image;
}

void BM_Fit(benchmark::State& state) {
  const ModelSpec& spec = SpecAt(static_cast<int>(state.range(0)));
  const CalibrationInput input = bench::InputOf(Chart());
  const FitLoss loss = state.range(1) ? FitLoss::kCiede2000 : FitLoss::kXyzLeastSquares;
  for (auto _ : state)
    benchmark::DoNotOptimize(FitModel(spec, input.camera_rgb, input.reference_xyz, input.white_xyz, 1e-3, loss));
  state.SetLabel(spec.Name() + (state.range(1) ? " ciede2000" : " xyz"));
}
BENCHMARK(BM_Fit)->ArgsProduct({{0, 1, 2, 3, 4, 5}, {0, 1}})->Unit(benchmark::kMicrosecond);

void BM_CalibrateWithLoo(benchmark::State& state) {
  CalibrationOptions options;
  options.candidates = {SpecAt(static_cast<int>(state.range(0)))};
  const CalibrationInput input = bench::InputOf(Chart());
  for (auto _ : state) benchmark::DoNotOptimize(Calibrate(input, options));
  state.SetLabel(options.candidates[0].Name());
}
BENCHMARK(BM_CalibrateWithLoo)->DenseRange(0, 5)->Unit(benchmark::kMicrosecond);

void BM_ApplyMegapixel(benchmark::State& state) {
  const ModelSpec& spec = SpecAt(static_cast<int>(state.range(0)));
  ColorModel model;
  for (const auto& m : Chart().summary.models)
    if (m.spec == spec) model = m.model;
  const cv::Mat image = MegapixelImage();
  cv::Mat xyz;
  for (auto _ : state) benchmark::DoNotOptimize(CameraToXyz(model, image, cv::Mat(), ApplyOptions{64.0, 1.0}, &xyz));
  state.SetBytesProcessed(state.iterations() * static_cast<std::int64_t>(image.total() * image.elemSize()));
  state.SetLabel(spec.Name());
}
BENCHMARK(BM_ApplyMegapixel)->DenseRange(0, 5)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_MemoryPass(benchmark::State& state) {
  const cv::Mat image = MegapixelImage();
  cv::Mat out;
  for (auto _ : state) {
    image.convertTo(out, CV_32FC3);
    benchmark::DoNotOptimize(out.data);
  }
  state.SetBytesProcessed(state.iterations() * static_cast<std::int64_t>(image.total() * image.elemSize()));
}
BENCHMARK(BM_MemoryPass)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_Srgb8Megapixel(benchmark::State& state) {
  cv::Mat xyz, srgb;
  CameraToXyz(Chart().summary.chosen_model(), MegapixelImage(), cv::Mat(), ApplyOptions{64.0, 1.0}, &xyz);
  for (auto _ : state) benchmark::DoNotOptimize(XyzToSrgb8(xyz, Chart().reference.white_xyz, &srgb));
}
BENCHMARK(BM_Srgb8Megapixel)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace photorig::solvers::color

BENCHMARK_MAIN();
