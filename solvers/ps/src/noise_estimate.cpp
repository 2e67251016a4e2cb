#include "noise_estimate.h"

#include "lambertian_tiles.h"
#include "model_selection.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <span>
#include <vector>

namespace photorig::solvers::ps::internal {

NoiseModel EstimateNoise(const PhotometricStack& stack, const LambertianOptions& thresholds) {
  struct Sample {
    double signal, variance;
    int dof;
  };
  const int pixels = stack.width() * stack.height();
  // About 8000 pixels, as runs of 32 neighbours spread over the image: a
  // pixel's samples lie in K planes, and lone pixels every few apart would
  // pull nearly every cache line of the stack from memory for one sample each.
  constexpr int kTarget = 8000, kRun = 32;
  const int run_stride = std::max(kRun, pixels / (kTarget / kRun));
  // Least squares on each sampled pixel's usable samples, by the Lambertian
  // pass's own kernel: the noise estimate then costs a fraction of the pass.
  const PixelResiduals fitter(thresholds, stack);
  if (!fitter.ok()) return stack.noise;
  std::vector<PixelResiduals::Run> runs;
  for (int run = 0; run < pixels; run += run_stride) runs.push_back({run, std::min(kRun, pixels - run)});
  std::vector<std::size_t> first_fit(runs.size() + 1, 0);
  for (std::size_t r = 0; r < runs.size(); ++r) first_fit[r + 1] = first_fit[r] + runs[r].count;
  std::vector<PixelResidual> fits(first_fit.back());
  const int threads = thresholds.num_threads > 0 ? thresholds.num_threads : omp_get_max_threads();
#pragma omp parallel num_threads(threads)
  {
    // One contiguous share of the runs per thread, one call each.
    const std::size_t count = runs.size(), thread = omp_get_thread_num(), shares = omp_get_num_threads();
    const std::size_t begin = count * thread / shares, end = count * (thread + 1) / shares;
    if (begin < end)
      fitter.Fit(std::span(runs).subspan(begin, end - begin), fits.data() + first_fit[begin]);
  }
  std::vector<Sample> samples;
  const std::uint8_t* mask = stack.mask.empty() ? nullptr : stack.mask.ptr<std::uint8_t>();
  for (std::size_t r = 0; r < runs.size(); ++r) {
    for (int i = 0; i < runs[r].count; ++i) {
      const PixelResidual& fit = fits[first_fit[r] + i];
      if ((mask && mask[runs[r].begin + i] == 0) || !fit.conditioned || fit.usable < 6) continue;
      // RSS ~ (n - 3) / n (read^2 sum 1/s^2 + gain sum (I - D)/s^2): per pixel
      // a residual variance and a signal in input units (with equal scales
      // s, RSS s^2 / (n - 3) and the mean of I - D).
      const double n = fit.usable, weight = fit.sum_inverse_scale2;
      samples.push_back({fit.sum_signal_inverse_scale2 / weight, fit.rss * n / ((n - 3.0) * weight), fit.usable - 3});
    }
  }
  NoiseModel noise = stack.noise;
  if (samples.size() < 16) return noise;
  std::vector<double> dofs;
  for (const Sample& sample : samples) dofs.push_back(sample.dof);
  std::nth_element(dofs.begin(), dofs.begin() + dofs.size() / 2, dofs.end());
  const int typical_dof = static_cast<int>(dofs[dofs.size() / 2]);
  constexpr double kQuantile = 0.1;
  const double bias = ChiSquareQuantiles(typical_dof, kQuantile)[typical_dof] / typical_dof;
  auto corrected_lower_decile = [bias](std::vector<double> values) {
    auto at = values.begin() + static_cast<std::ptrdiff_t>(kQuantile * (values.size() - 1));
    std::nth_element(values.begin(), at, values.end());
    return *at / bias;
  };
  const bool read_known = stack.noise.read_sigma > 0.0, gain_known = stack.noise.shot_gain > 0.0;
  double read2 = read_known ? stack.noise.read_sigma * stack.noise.read_sigma : 0.0;
  double gain = gain_known ? stack.noise.shot_gain : 0.0;
  // Unknown read noise comes from the darkest tenth of the pixels, where shot
  // noise matters least, refined once the gain is known. (The samples are in
  // run order whatever the thread count, so the partition is reproducible.)
  const std::size_t darkest = std::max<std::size_t>(8, samples.size() / 10);
  if (!read_known)
    std::nth_element(samples.begin(), samples.begin() + (darkest - 1), samples.end(),
                     [](const Sample& a, const Sample& b) { return a.signal < b.signal; });
  // Given the gain, read^2 is where the lower decile of v_p / (read^2 + gain
  // signal_p) over those pixels equals the chi-square lower decile (bias); the
  // ratio is decreasing in read^2, so bisection finds it. (The lower decile of
  // v_p - gain signal_p instead comes out low by gain signal_p (1 / bias - 1):
  // 0.8 DN for 3 DN of read noise where shot noise dominated the dark pixels.)
  auto read_variance = [&](double gain) {
    std::vector<double> ratios(darkest);
    auto decile_ratio = [&](double r2) {
      for (std::size_t i = 0; i < darkest; ++i)
        ratios[i] = samples[i].variance / std::max(r2 + gain * std::max(samples[i].signal, 0.0), 1e-300);
      auto at = ratios.begin() + static_cast<std::ptrdiff_t>(kQuantile * (darkest - 1));
      std::nth_element(ratios.begin(), at, ratios.end());
      return *at;
    };
    if (decile_ratio(0.0) <= bias) return 0.0;  // shot noise alone explains the darkest pixels
    double low = 0.0, high = 1.0;
    while (decile_ratio(high) > bias) high *= 4.0;
    for (int step = 0; step < 60; ++step) {
      const double middle = 0.5 * (low + high);
      (decile_ratio(middle) > bias ? low : high) = middle;
    }
    return 0.5 * (low + high);
  };
  for (int round = 0; round < (read_known ? 1 : 2); ++round) {
    if (!read_known) read2 = read_variance(gain);
    if (gain_known) break;  // the read noise was all that was missing
    std::vector<double> gains;
    for (const Sample& sample : samples)
      if (sample.signal > 0.0) gains.push_back((sample.variance - read2) / sample.signal);
    gain = gains.empty() ? 0.0 : std::max(0.0, corrected_lower_decile(gains));
  }
  noise.shot_gain = gain;
  noise.read_sigma = std::sqrt(read2);
  return noise;
}

SolveNoise NoiseForSolve(const PhotometricStereoOptions& options, bool refine, const PhotometricStack& stack,
                         const LambertianOptions& lambertian) {
  SolveNoise noise{stack.noise, false, lambertian.shadow_threshold};
  // A shadow threshold in read-noise sigmas needs the read noise; `l2` uses
  // every sample whatever the threshold, so it is not estimated for `l2`.
  const bool read_noise_wanted = options.shadow_threshold_read_sigmas > 0.0 && options.method != Method::kL2 &&
                                 !(stack.noise.read_sigma > 0.0);
  const bool estimable = options.estimate_noise && stack.IsValid(nullptr) && lambertian.IsValid(nullptr);
  if (estimable && ((refine && stack.noise.shot_gain == 0.0) || read_noise_wanted)) {
    noise.model = EstimateNoise(stack, lambertian);
    noise.estimated = true;
  }
  const double absolute_threshold = lambertian.shadow_threshold;
  auto raise_threshold = [&] {
    noise.shadow_threshold =
        std::max(absolute_threshold, options.shadow_threshold_read_sigmas * noise.model.read_sigma);
  };
  raise_threshold();
  // An estimated read noise came from fits of the samples just above the
  // absolute threshold, shadows lifted by noise among them: it is estimated
  // once more without them, and the threshold taken from that (a third round
  // moved the estimate by under 2 % on re-imported simulated runs).
  LambertianOptions raised = lambertian;
  raised.shadow_threshold = noise.shadow_threshold;
  if (noise.estimated && !(stack.noise.read_sigma > 0.0) && noise.shadow_threshold > absolute_threshold &&
      raised.IsValid(nullptr)) {
    noise.model = EstimateNoise(stack, raised);
    raise_threshold();
  }
  return noise;
}

}  // namespace photorig::solvers::ps::internal
