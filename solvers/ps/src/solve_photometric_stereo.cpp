// SolvePhotometricStereo (photometric_stereo.h): the options and the signal
// checked, the noise model completed, then the Lambertian pass with each tile
// refined as it is written (tile_refiner.h). Apart from photometric_stereo.h
// so that the helpers it runs can take that header's types.
#include "photorig/solvers/ps/photometric_stereo.h"

#include "lambertian_tiles.h"
#include "model_selection.h"
#include "noise_estimate.h"
#include "tile_refiner.h"

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <string>

namespace photorig::solvers::ps {
namespace {

// Counts the pixels of the tiles every thread has finished and reports them
// from OpenMP's thread 0, the caller's, so the callback never runs
// concurrently; one atomic add per tile, nothing when no one listens.
class TileProgress {
 public:
  TileProgress(const solvers::core::ProgressCallback& callback, const char* stage, std::int64_t pixels)
      : throttle_(callback, stage, pixels), listening_(static_cast<bool>(callback)) {}
  void TileDone(int thread, int pixels) {
    if (!listening_) return;
    const std::int64_t done = done_.fetch_add(pixels, std::memory_order_relaxed) + pixels;
    if (thread == 0) throttle_.Update(done);
  }
  void Finish() { throttle_.Finish(); }

 private:
  solvers::core::ProgressThrottle throttle_;
  const bool listening_;
  std::atomic<std::int64_t> done_{0};
};
// Empty when at least three images rise above the dark over enough pixels
// (or the stack gives no dark and read noise to judge by); else why not.
std::string MissingSignal(const PhotometricStereoOptions& options, const PhotometricStack& stack) {
  if (options.min_signal_read_sigmas <= 0.0 || stack.dark.empty() || !(stack.noise.read_sigma > 0.0) ||
      !stack.IsValid(nullptr))
    return {};
  const float threshold = static_cast<float>(options.min_signal_read_sigmas * stack.noise.read_sigma);
  const std::size_t pixels = stack.dark.total();
  const float* dark = stack.dark.ptr<float>();
  int with_signal = 0;
  for (const cv::Mat& image : stack.images) {
    const float* values = image.ptr<float>();
    int above = 0;
    for (std::size_t i = 0; i < pixels && above < options.min_signal_pixels; ++i) above += values[i] - dark[i] > threshold;
    if (above >= options.min_signal_pixels && ++with_signal >= 3) return {};
  }
  char text[400];
  std::snprintf(text, sizeof(text),
                "no usable signal: %d of %d images have %d pixels %g read-noise sigmas (%.1f) above the dark, and a "
                "normal needs 3 lit images; were the lights on? Check the light controller's power and wiring, and "
                "that nothing covers the lens",
                with_signal, stack.light_count(), options.min_signal_pixels, options.min_signal_read_sigmas, threshold);
  return text;
}

}  // namespace

SolverSummary SolvePhotometricStereo(const PhotometricStereoOptions& options, const PhotometricStack& stack,
                                     NormalMap* result) {
  const solvers::core::SolveTimer timer;
  std::string why;
  if (!options.IsValid(&why)) {
    SolverSummary summary;
    summary.method = MethodName(options.method);
    summary.End(Termination::kInvalidOptions, "invalid options: " + why);
    return summary;
  }
  if (const std::string missing = MissingSignal(options, stack); !missing.empty()) {
    SolverSummary summary;
    summary.method = MethodName(options.method);
    summary.light_count = stack.light_count();
    summary.End(Termination::kFailure, missing);
    return summary;
  }
  LambertianOptions lambertian = options.lambertian;
  lambertian.exclude_unusable_samples = options.method != Method::kL2;
  // The adequacy tests need the noise; what the stack does not give is
  // estimated from the data first, so that the Lambertian pass can already
  // judge its own fits (its confidence) and spare them a second look.
  const bool refine = options.method == Method::kRobust || options.method == Method::kBlinnPhong ||
                      options.method == Method::kAuto || options.method == Method::kLowFrequency;
  PhotometricStack working = stack;
  const internal::SolveNoise noise = internal::NoiseForSolve(options, refine, stack, lambertian);
  working.noise = noise.model;
  const bool noise_estimated = noise.estimated;
  lambertian.shadow_threshold = noise.shadow_threshold;
  if (!lambertian.IsValid(&why)) {
    SolverSummary summary;
    summary.method = MethodName(options.method);
    summary.termination = Termination::kInvalidOptions;
    summary.message = "invalid options: " + why + " (the shadow threshold was raised to " +
                      std::to_string(options.shadow_threshold_read_sigmas) + " read-noise sigmas, " +
                      std::to_string(lambertian.shadow_threshold) + ")";
    summary.shadow_threshold = lambertian.shadow_threshold;
    return summary;
  }
  TileProgress progress(options.progress, MethodName(options.method),
                        static_cast<std::int64_t>(stack.width()) * stack.height());
  // Setup is everything before the first tile (the noise model included);
  // solve_ms covers the tiles and, for refining methods, steps 5-7 after them.
  const double setup_ms = timer.ElapsedMs();
  auto finish = [&](SolverSummary* summary) {
    summary->setup_ms = setup_ms;
    summary->total_ms = timer.ElapsedMs();
    summary->solve_ms = summary->total_ms - setup_ms;
    // Every step may succeed and still leave no pixel with a normal (a mask
    // that selects none, every pixel in shadow): no result to use.
    if (summary->IsSolutionUsable() && summary->pixels_solved == 0)
      summary->End(Termination::kFailure,
                   "no pixel could be solved: " + std::to_string(summary->pixels_outside_mask) + " outside the mask, " +
                       std::to_string(summary->pixels_too_few_lights) + " with fewer than 3 usable lights, " +
                       std::to_string(summary->pixels_ill_conditioned) + " ill-conditioned");
  };
  if (!refine) {
    const internal::TileVisitor count_tiles = [&](int thread, int, int count) { progress.TileDone(thread, count); };
    SolverSummary summary =
        internal::SolveLambertianTiles(lambertian, working, result, options.progress ? count_tiles : nullptr);
    summary.tiles_ms = timer.ElapsedMs() - setup_ms;
    if (summary.IsSolutionUsable()) progress.Finish();
    summary.method = MethodName(options.method);
    summary.pixels_lambertian = summary.pixels_solved;
    summary.noise_estimated = noise_estimated;
    summary.noise_read_sigma = working.noise.read_sigma;
    summary.noise_shot_gain = working.noise.shot_gain;
    summary.shadow_threshold = lambertian.shadow_threshold;
    finish(&summary);
    return summary;
  }
  if (!(working.noise.read_sigma > 0.0)) working.noise.read_sigma = 1e-9;  // noise-free: any residual counts
  const internal::ModelLadder ladder(options.method, options.selection, working.light_count());
  const int threads = options.lambertian.num_threads > 0 ? options.lambertian.num_threads : omp_get_max_threads();
  internal::TileRefiner refiner(options, lambertian, working, ladder, threads, result);
  // `low-frequency` refines no tile: its fit (step 7) takes every solved pixel after the pass.
  const bool refine_tiles = options.method != Method::kLowFrequency;
  SolverSummary summary = internal::SolveLambertianTiles(
      lambertian, working, result,
      [&](int thread, int begin, int count) {
        if (refine_tiles) refiner.RefineTile(thread, begin, count);
        progress.TileDone(thread, count);
      },
      [&](int thread) {
        if (refine_tiles) refiner.Finish(thread);
      });
  const double tiles_end_ms = timer.ElapsedMs();
  summary.tiles_ms = tiles_end_ms - setup_ms;
  if (!refine_tiles) summary.pixels_lambertian = summary.pixels_solved;
  summary.method = MethodName(options.method);
  summary.shadow_threshold = lambertian.shadow_threshold;
  if (!summary.IsSolutionUsable()) {
    finish(&summary);
    return summary;
  }
  refiner.ShareLobe();
  const double shared_lobe_end_ms = timer.ElapsedMs();
  summary.shared_lobe_ms = shared_lobe_end_ms - tiles_end_ms;
  refiner.OfferLowFrequency();
  summary.low_frequency_ms = timer.ElapsedMs() - shared_lobe_end_ms;
  summary.noise_estimated = noise_estimated;
  summary.noise_read_sigma = working.noise.read_sigma;
  summary.noise_shot_gain = working.noise.shot_gain;
  refiner.AddCounts(&summary);
  progress.Finish();
  finish(&summary);
  return summary;
}

}  // namespace photorig::solvers::ps
