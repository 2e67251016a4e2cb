#include "photorig/solvers/tomography/absorbance.h"

#include <cmath>

namespace photorig::solvers::tomography {

bool AbsorbanceOptions::IsValid(std::string* why) const {
  if (!(saturation_dn >= 0) || !std::isfinite(saturation_dn)) return core::Refuse(why, "saturation_dn must be finite and >= 0");
  if (!(min_flat_signal_dn > 0) || !std::isfinite(min_flat_signal_dn))
    return core::Refuse(why, "min_flat_signal_dn must be finite and > 0");
  return true;
}

namespace {

// Per-pixel mean and (with two or more frames) unbiased temporal variance.
void MeanAndVariance(const std::vector<std::vector<std::uint16_t>>& frames, std::size_t pixels,
                     std::vector<double>* mean, std::vector<double>* variance) {
  mean->assign(pixels, 0.0);
  variance->assign(pixels, 0.0);
  const double n = static_cast<double>(frames.size());
  for (const auto& f : frames)
    for (std::size_t p = 0; p < pixels; ++p) (*mean)[p] += f[p];
  for (double& m : *mean) m /= n;
  if (frames.size() < 2) return;
  for (const auto& f : frames)
    for (std::size_t p = 0; p < pixels; ++p) (*variance)[p] += (f[p] - (*mean)[p]) * (f[p] - (*mean)[p]);
  for (double& v : *variance) v /= n - 1.0;
}

}  // namespace

AbsorbanceSummary ComputeAbsorbance(const Geometry& geometry, const std::vector<std::vector<std::uint16_t>>& projections,
                                    const std::vector<std::vector<std::uint16_t>>& flats,
                                    const std::vector<std::vector<std::uint16_t>>& darks,
                                    const AbsorbanceOptions& options, Absorbance* absorbance) {
  solvers::core::SolveTimer timer;
  AbsorbanceSummary summary;
  using solvers::core::Termination;
  std::string why;
  if (!options.IsValid(&why)) return timer.End(&summary, Termination::kInvalidOptions, why);
  if (!geometry.IsValid(&why)) return timer.End(&summary, Termination::kInvalidInput, why);
  const auto pixels = static_cast<std::size_t>(geometry.pixels_per_view());
  if (projections.size() != static_cast<std::size_t>(geometry.views()))
    return timer.End(&summary, Termination::kInvalidInput,
                     std::to_string(projections.size()) + " projections for " + std::to_string(geometry.views()) +
                         " view angles");
  if (flats.empty() || darks.empty())
    return timer.End(&summary, Termination::kInvalidInput, "dark/flat correction needs at least one flat and one dark frame");
  for (const auto* set : {&projections, &flats, &darks})
    for (const auto& frame : *set)
      if (frame.size() != pixels)
        return timer.End(&summary, Termination::kInvalidInput,
                         "a frame has " + std::to_string(frame.size()) + " pixels; the detector has " +
                             std::to_string(pixels));
  std::vector<double> dark, dark_var, flat, flat_var;
  MeanAndVariance(darks, pixels, &dark, &dark_var);
  MeanAndVariance(flats, pixels, &flat, &flat_var);

  // The noise model var(DN) = read + gain * signal, fitted over the flat field.
  summary.noise_estimated = flats.size() >= 2 && darks.size() >= 2;
  if (summary.noise_estimated) {
    double read = 0.0, signal = 0.0, excess = 0.0;
    for (std::size_t p = 0; p < pixels; ++p) read += dark_var[p];
    read /= static_cast<double>(pixels);
    for (std::size_t p = 0; p < pixels; ++p) {
      signal += flat[p] - dark[p];
      excess += flat_var[p] - read;
    }
    summary.read_variance_dn2 = read;
    summary.gain_dn_per_dn = signal > 0 ? std::max(0.0, excess / signal) : 0.0;
  }
  const double quantisation = 1.0 / 12.0;  // rounding to whole DN
  const auto n_flats = static_cast<double>(flats.size());

  const std::int64_t rays = geometry.rays();
  summary.rays = rays;
  absorbance->b.setZero(rays);
  absorbance->valid.assign(static_cast<std::size_t>(rays), 0);
  if (summary.noise_estimated)
    absorbance->variance.setZero(rays);
  else
    absorbance->variance.resize(0);
  const bool check_saturation = options.saturation_dn > 0;
  std::vector<std::uint8_t> flat_saturated(pixels, 0);
  for (const auto& f : flats)
    for (std::size_t p = 0; p < pixels; ++p)
      if (check_saturation && f[p] >= options.saturation_dn) flat_saturated[p] = 1;
  timer.SetupDone(&summary);

  double sigma_sum = 0.0;
  std::int64_t usable = 0;
  for (int view = 0; view < geometry.views(); ++view) {
    const auto& frame = projections[static_cast<std::size_t>(view)];
    for (std::size_t p = 0; p < pixels; ++p) {
      const std::int64_t ray = view * static_cast<std::int64_t>(pixels) + static_cast<std::int64_t>(p);
      const double f = flat[p] - dark[p], l = frame[p] - dark[p];
      if ((check_saturation && frame[p] >= options.saturation_dn) || flat_saturated[p]) {
        ++summary.flagged_saturated;
        continue;
      }
      if (f < options.min_flat_signal_dn) {
        ++summary.flagged_no_flat;
        continue;
      }
      if (l <= 0.0) {
        ++summary.flagged_non_positive;
        continue;
      }
      absorbance->b[ray] = static_cast<float>(-std::log(l / f));
      absorbance->valid[static_cast<std::size_t>(ray)] = 1;
      ++usable;
      if (summary.noise_estimated) {
        const double var_l = summary.read_variance_dn2 + quantisation + summary.gain_dn_per_dn * l;
        const double var_f = (summary.read_variance_dn2 + quantisation + summary.gain_dn_per_dn * f) / n_flats;
        const double var_b = var_l / (l * l) + var_f / (f * f);
        absorbance->variance[ray] = static_cast<float>(var_b);
        sigma_sum += var_b;
      }
    }
  }
  if (usable > 0) summary.mean_b_sigma = std::sqrt(sigma_sum / static_cast<double>(usable));
  timer.Finish(&summary);
  if (usable == 0) {
    summary.End(solvers::core::Termination::kFailure,
                "no usable pixel: " + std::to_string(summary.flagged_saturated) + " saturated, " +
                    std::to_string(summary.flagged_no_flat) + " without flat signal, " +
                    std::to_string(summary.flagged_non_positive) + " at or below the dark level");
    return summary;
  }
  summary.termination = solvers::core::Termination::kSuccess;
  if (summary.flagged() > 0)
    summary.message = std::to_string(summary.flagged()) + " of " + std::to_string(rays) +
                      " pixels flagged and left out (" + std::to_string(summary.flagged_saturated) + " saturated, " +
                      std::to_string(summary.flagged_no_flat) + " without flat signal, " +
                      std::to_string(summary.flagged_non_positive) + " at or below the dark level)";
  return summary;
}

}  // namespace photorig::solvers::tomography
