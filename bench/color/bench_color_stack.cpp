// Turning a colour run's raw frames into a colour stack, per 1 MP 12-bit
// RGGB frame: demosaicing (bilinear and edge-aware), then demosaicing plus the
// colour model (root-poly-2 from the simulated Nikon 5100 chart), against a
// bandwidth floor: the 16-bit -> float conversion of a demosaiced frame, the
// least any per-pixel pass to a float colour stack does. Bytes processed
// count the raw frame, so the figures compare as frames per second.

#include "chart_capture.h"
#include "photorig/solvers/color/region_demosaic.h"
#include "photorig/daemon/pipelines/color_stack.h"

#include <benchmark/benchmark.h>
#include <opencv2/imgproc.hpp>

namespace photorig::daemon {
namespace {

using solvers::color::DemosaicMethod;

constexpr int kSide = 1024;

cv::Mat RawMosaic() {
  cv::Mat raw(kSide, kSide, CV_16U);
  cv::randu(raw, cv::Scalar(64), cv::Scalar(4000));
  return raw;
}

const solvers::color::ColorModel& RootPoly2() {
  static const solvers::color::ColorModel model = [] {
    const auto chart = solvers::color::bench::SimulatedChart("nikon-5100", solvers::color::Illuminant::kD65, solvers::color::CalibrationOptions{});
    for (const auto& m : chart.summary.models)
      if (m.spec.Name() == "root-poly-2") return m.model;
    return chart.summary.chosen_model();
  }();
  return model;
}

void SetRawBytes(benchmark::State& state) {
  state.SetBytesProcessed(state.iterations() * static_cast<std::int64_t>(kSide) * kSide * 2);
}

void BM_Demosaic(benchmark::State& state) {
  const DemosaicMethod method = state.range(0) ? DemosaicMethod::kEdgeAware : DemosaicMethod::kBilinear;
  const cv::Mat raw = RawMosaic();
  for (auto _ : state) benchmark::DoNotOptimize(DemosaicToRgb(raw, "RGGB", method).data);
  SetRawBytes(state);
  state.SetLabel(DemosaicMethodName(method));
}
BENCHMARK(BM_Demosaic)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// Demosaicing within regions (the SVBRDF refit), on a checker of two labels
// in 16 px squares: most pixels see one label, as on a painted object, and
// the edges take the 5 x 5 fallback. Arg: 1 = one label everywhere.
void BM_DemosaicWithinRegions(benchmark::State& state) {
  const cv::Mat raw = RawMosaic();
  cv::Mat regions(kSide, kSide, CV_8U);
  for (int y = 0; y < kSide; ++y)
    for (int x = 0; x < kSide; ++x)
      regions.at<std::uint8_t>(y, x) = state.range(0) ? 0 : static_cast<std::uint8_t>(((y / 16) + (x / 16)) & 1);
  cv::Mat bgr;
  for (auto _ : state) {
    solvers::color::DemosaicWithinRegions(raw, "RGGB", regions, &bgr);
    benchmark::DoNotOptimize(bgr.data);
  }
  SetRawBytes(state);
  state.SetLabel(state.range(0) ? "one region" : "16 px checker");
}
BENCHMARK(BM_DemosaicWithinRegions)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// One frame's vote on the edges of the same checker (every pixel within 2 px
// of an edge is contested: 44 % of the frame).
void BM_RegionEdgeVote(benchmark::State& state) {
  const cv::Mat raw = RawMosaic();
  cv::Mat regions(kSide, kSide, CV_8U);
  for (int y = 0; y < kSide; ++y)
    for (int x = 0; x < kSide; ++x) regions.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(((y / 16) + (x / 16)) & 1);
  solvers::color::RegionEdgeVote vote("RGGB", regions, {});
  for (auto _ : state) benchmark::DoNotOptimize(vote.Add(raw).termination);
  SetRawBytes(state);
  state.counters["contested"] = vote.contested_pixels();
}
BENCHMARK(BM_RegionEdgeVote)->Unit(benchmark::kMillisecond)->UseRealTime();

// What LoadRunColorStack does per lit frame: demosaic, to float, subtract the dark, colour model.
void BM_DemosaicAndColorModel(benchmark::State& state) {
  const cv::Mat raw = RawMosaic();
  const cv::Mat dark(kSide, kSide, CV_32FC3, cv::Scalar::all(64));
  const solvers::color::ColorModel& model = RootPoly2();
  for (auto _ : state) {
    cv::Mat rgb;
    DemosaicToRgb(raw, "RGGB", DemosaicMethod::kBilinear).convertTo(rgb, CV_32F);
    rgb -= dark;
    ApplyColorModelInPlace(model, &rgb);
    benchmark::DoNotOptimize(rgb.data);
  }
  SetRawBytes(state);
  state.SetLabel(model.spec.Name());
}
BENCHMARK(BM_DemosaicAndColorModel)->Unit(benchmark::kMillisecond)->UseRealTime();

// The least a pass to a float colour stack must do: read 16-bit R, G, B and
// write float R, G, B (6 bytes in, 12 out per pixel), one convertTo.
void BM_BandwidthFloor(benchmark::State& state) {
  cv::Mat rgb16(kSide, kSide, CV_16UC3);
  cv::randu(rgb16, cv::Scalar::all(64), cv::Scalar::all(4000));
  cv::Mat out;
  for (auto _ : state) {
    rgb16.convertTo(out, CV_32F);
    benchmark::DoNotOptimize(out.data);
  }
  SetRawBytes(state);
}
BENCHMARK(BM_BandwidthFloor)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace photorig::daemon

BENCHMARK_MAIN();
