// Checkerboard lens calibration of 13 simulated photographs (384 x 384, the
// dome's lens): the whole calibration with each distortion model fixed and
// with the model chosen (which fits every model to the corners found once),
// and the corner search alone. Its images are rendered once, outside the timing.
#include "checkerboard_scene.h"
#include "photorig/solvers/camera/calibration.h"

#include <benchmark/benchmark.h>
#include <opencv2/calib3d.hpp>

#include <optional>

namespace {

using namespace photorig;
using solvers::camera::DistortionModel;

const std::vector<cv::Mat>& Images() {
  static const std::vector<cv::Mat> images = testing::Render(testing::TrueCamera(), testing::Poses());
  return images;
}

// Arg: a DistortionModel, or 5 for the chosen model.
void BM_Calibrate(benchmark::State& state) {
  solvers::camera::CheckerboardCalibrationOptions options;
  options.inner_corners_cols = 9;
  options.inner_corners_rows = 6;
  options.square_mm = 10.0;
  if (state.range(0) < 5) options.distortion = static_cast<DistortionModel>(state.range(0));
  const std::vector<cv::Mat>& images = Images();
  double fit_ms = 0.0;
  for (auto _ : state) {
    const auto summary = solvers::camera::CalibrateFromCheckerboards(options, images);
    if (!summary.IsSolutionUsable()) state.SkipWithError(summary.message.c_str());
    fit_ms += summary.solve_ms;
  }
  state.counters["solve_ms"] = fit_ms / static_cast<double>(state.iterations());
  state.SetLabel(options.distortion ? solvers::core::NameOf(solvers::camera::kDistortionModelNames, *options.distortion)
                                    : "chosen");
}
BENCHMARK(BM_Calibrate)->DenseRange(0, 5)->Unit(benchmark::kMillisecond);

// OpenCV's corner search and refinement on the 13 photographs: the share of
// a calibration no model choice changes.
void BM_FindCorners(benchmark::State& state) {
  const std::vector<cv::Mat>& images = Images();
  for (auto _ : state) {
    for (const cv::Mat& image : images) {
      std::vector<cv::Point2f> corners;
      cv::findChessboardCorners(image, cv::Size(9, 6), corners, cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
      benchmark::DoNotOptimize(corners.data());
    }
  }
}
BENCHMARK(BM_FindCorners)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
