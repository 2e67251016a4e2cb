#include "photorig/solvers/lighting/led_radiance.h"

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace photorig::solvers::lighting {
namespace {

constexpr double kPi = 3.14159265358979323846;

// y and t of every usable sample of one LED (see the header), with their weights.
struct LogSamples {
  std::vector<double> y, t, weight;
  int clipped = 0;
};

LogSamples GatherSamples(const LedRadianceOptions& options, const camera::PixelRays& rays, const SensorNoise& noise,
                         const cv::Mat& mask, const LedPlaneFrame& frame) {
  LogSamples samples;
  const Eigen::Vector3d& led = frame.position_mm;
  const double cos_origin = -frame.axis.dot(led.normalized());
  const double read_variance = noise.read_sigma_dn * noise.read_sigma_dn;
  for (int r = 0; r < mask.rows; r += options.stride_px)
    for (int c = 0; c < mask.cols; c += options.stride_px) {
      if (!mask.at<std::uint8_t>(r, c)) continue;
      if (!frame.raw.empty() && frame.raw.at<float>(r, c) >= options.saturation_level_dn) {
        ++samples.clipped;
        continue;
      }
      const double signal = frame.signal.at<float>(r, c);
      const double variance = read_variance + noise.shot_gain * std::max(signal, 0.0);
      if (!(signal > options.min_signal_sigmas * std::sqrt(variance))) continue;
      const Eigen::Vector3d to = led - rays.Point(r, c, options.plane_height_mm);
      const double distance2 = to.squaredNorm();
      const Eigen::Vector3d l = to / std::sqrt(distance2);
      const double cos_axis = -frame.axis.dot(l);
      if (!(l.z() > 0.0) || !(cos_axis > 0.0)) continue;  // grazing or outside the LED's cone
      const double model = frame.dn_per_radiance * options.albedo / kPi * (led.squaredNorm() / distance2) * l.z();
      samples.y.push_back(std::log(signal / model));
      samples.t.push_back(std::log(cos_axis / cos_origin));
      samples.weight.push_back(signal * signal / variance);
    }
  return samples;
}

struct LineFit {
  double intercept = 0.0, slope = 0.0;
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();  // for unit-variance weights
  double chi2 = 0.0;
};

// Weighted least squares of y = a + b t; with the slope fixed, of a alone.
LineFit FitLine(const LogSamples& s, std::optional<double> fixed_slope) {
  LineFit fit;
  const std::size_t n = s.y.size();
  if (fixed_slope) {
    double sw = 0.0, swy = 0.0;
    for (std::size_t i = 0; i < n; ++i) sw += s.weight[i], swy += s.weight[i] * (s.y[i] - *fixed_slope * s.t[i]);
    fit.intercept = swy / sw;
    fit.slope = *fixed_slope;
    fit.covariance(0, 0) = 1.0 / sw;
  } else {
    Eigen::Matrix2d normal = Eigen::Matrix2d::Zero();
    Eigen::Vector2d rhs = Eigen::Vector2d::Zero();
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector2d row(1.0, s.t[i]);
      normal.noalias() += s.weight[i] * row * row.transpose();
      rhs.noalias() += s.weight[i] * s.y[i] * row;
    }
    const Eigen::Vector2d solution = normal.ldlt().solve(rhs);
    fit.intercept = solution(0), fit.slope = solution(1);
    fit.covariance = normal.inverse();
  }
  for (std::size_t i = 0; i < n; ++i) {
    const double e = s.y[i] - fit.intercept - fit.slope * s.t[i];
    fit.chi2 += s.weight[i] * e * e;
  }
  return fit;
}

// The RMS of y's residuals beyond what the noise explains: the model's own
// relative error per sample (the noise's share is mean 1 / weight).
double ExcessRelativeRms(const LogSamples& s, const LineFit& fit) {
  double residual = 0.0, noise = 0.0;
  for (std::size_t i = 0; i < s.y.size(); ++i) {
    residual += std::pow(s.y[i] - fit.intercept - fit.slope * s.t[i], 2);
    noise += 1.0 / s.weight[i];
  }
  return std::sqrt(std::max(0.0, residual - noise) / static_cast<double>(s.y.size()));
}

LedRadianceEstimate FitLed(const LedRadianceOptions& options, const LogSamples& samples, double stated_exponent) {
  LedRadianceEstimate estimate;
  estimate.samples = static_cast<int>(samples.y.size());
  if (estimate.samples < options.min_samples) {
    estimate.note = std::to_string(estimate.samples) + " plane samples above the noise, fewer than " +
                    std::to_string(options.min_samples) + " (clipped: " + std::to_string(samples.clipped) +
                    "): is the LED lit and the plane in view?";
    return estimate;
  }
  const LineFit kept = FitLine(samples, stated_exponent);
  const LineFit free = FitLine(samples, std::nullopt);
  const double n = estimate.samples;
  // The free fit's residual variance per unit weight: 1 where the noise
  // model alone explains the scatter, more where the model misses shading.
  const double scale = std::max(1.0, free.chi2 / (n - 2.0));
  if (options.exponent != ExponentRule::kKeep) estimate.bic_gain = (kept.chi2 - free.chi2) / scale - std::log(n);
  const bool fit_exponent =
      options.exponent == ExponentRule::kFit || (options.exponent == ExponentRule::kChoose && estimate.bic_gain > 0.0);
  const LineFit& chosen = fit_exponent ? free : kept;
  const double chosen_scale = fit_exponent ? scale : std::max(1.0, kept.chi2 / (n - 1.0));
  estimate.exponent_fitted = fit_exponent;
  estimate.intensity = std::exp(chosen.intercept);
  estimate.intensity_std = estimate.intensity * std::sqrt(chosen.covariance(0, 0) * chosen_scale);
  estimate.cos_exponent = chosen.slope;
  estimate.cos_exponent_std = fit_exponent ? std::sqrt(chosen.covariance(1, 1) * chosen_scale) : 0.0;
  estimate.model_error = ExcessRelativeRms(samples, chosen);
  if (!fit_exponent && options.exponent == ExponentRule::kChoose)
    estimate.note = "the plane does not tell the exponent from the stated one: kept";
  if (estimate.model_error > options.max_model_error) {
    char text[200];
    std::snprintf(text, sizeof(text),
                  "the plane's shading departs from the model by %.1f %% RMS beyond the noise (limit %.1f %%): a "
                  "shadow or reflection on the plane, or the LED is not where the rig says",
                  100.0 * estimate.model_error, 100.0 * options.max_model_error);
    estimate.note = text;
    return estimate;
  }
  if (!(estimate.cos_exponent >= 0.0)) {
    estimate.note = "the fitted exponent is negative: the LED brightens away from its axis, which no emitter does";
    return estimate;
  }
  estimate.usable = true;
  return estimate;
}

// The plane's pixels: bright under the LEDs together, away from its edge.
cv::Mat PlaneMask(const LedRadianceOptions& options, const std::vector<LedPlaneFrame>& frames) {
  cv::Mat mean = cv::Mat::zeros(frames.front().signal.size(), CV_32F);
  for (const LedPlaneFrame& frame : frames) mean += frame.signal;
  mean /= static_cast<double>(frames.size());
  std::vector<float> values(mean.begin<float>(), mean.end<float>());
  const std::size_t at = static_cast<std::size_t>(0.95 * static_cast<double>(values.size() - 1));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(at), values.end());
  cv::Mat mask = mean > options.plane_threshold_fraction * values[at];
  if (options.edge_margin_px > 0) {
    const int size = 2 * options.edge_margin_px + 1;
    cv::erode(mask, mask, cv::getStructuringElement(cv::MORPH_ELLIPSE, {size, size}));
  }
  return mask;
}

std::string CheckInputs(const camera::Camera& camera, const SensorNoise& noise, const std::vector<LedPlaneFrame>& frames) {
  if (std::string why; !camera.IsValid(&why)) return "camera: " + why;
  if (frames.empty()) return "no frames";
  if (!(noise.read_sigma_dn > 0.0 || noise.shot_gain > 0.0))
    return "no noise model: the fit weights each sample by its noise (the run's manifest states it)";
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const LedPlaneFrame& f = frames[k];
    const std::string name = "frame " + std::to_string(k);
    if (f.signal.type() != CV_32F || f.signal.cols != camera.width_px || f.signal.rows != camera.height_px)
      return name + ": the signal must be a CV_32F image of the camera's size";
    if (!f.raw.empty() && (f.raw.type() != CV_32F || f.raw.size() != f.signal.size()))
      return name + ": the raw image must be CV_32F of the signal's size";
    if (!(f.dn_per_radiance > 0.0)) return name + ": dn_per_radiance must be > 0";
    if (!(f.position_mm.z() > 0.0) || !f.position_mm.allFinite()) return name + ": the LED is not above the sample plane";
    if (!(std::abs(f.axis.norm() - 1.0) < 1e-6)) return name + ": the LED's axis is not a unit vector";
  }
  return {};
}

}  // namespace

bool LedRadianceOptions::IsValid(std::string* why) const {
  if (!(albedo > 0.0 && albedo <= 1.0)) return core::Refuse(why, "albedo must be within (0, 1]");
  if (!std::isfinite(plane_height_mm)) return core::Refuse(why, "plane_height_mm must be finite");
  if (!(min_signal_sigmas >= 0.0)) return core::Refuse(why, "min_signal_sigmas must be >= 0");
  if (!(plane_threshold_fraction > 0.0 && plane_threshold_fraction < 1.0))
    return core::Refuse(why, "plane_threshold_fraction must be within (0, 1)");
  if (edge_margin_px < 0) return core::Refuse(why, "edge_margin_px must be >= 0");
  if (stride_px < 1) return core::Refuse(why, "stride_px must be >= 1");
  if (min_samples < 3) return core::Refuse(why, "min_samples must be >= 3");
  if (!(max_model_error > 0.0)) return core::Refuse(why, "max_model_error must be > 0");
  return true;
}

LedRadianceSummary CalibrateLedRadiance(const LedRadianceOptions& options, const camera::Camera& camera,
                                        const SensorNoise& noise, const std::vector<LedPlaneFrame>& frames) {
  core::SolveTimer timer;
  LedRadianceSummary summary;
  if (core::EndIfInvalid(options, &summary) || core::EndIfBadInput(CheckInputs(camera, noise, frames), &summary))
    return summary;
  const camera::PixelRays rays(camera);
  summary.plane_mask = PlaneMask(options, frames);
  summary.plane_pixels = cv::countNonZero(summary.plane_mask);
  timer.SetupDone(&summary);
  summary.leds.resize(frames.size());
#pragma omp parallel for schedule(dynamic, 1)
  for (std::size_t k = 0; k < frames.size(); ++k)
    summary.leds[k] = FitLed(options, GatherSamples(options, rays, noise, summary.plane_mask, frames[k]),
                             frames[k].cos_exponent);
  std::string first_unusable;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    if (summary.leds[k].usable) {
      ++summary.usable;
    } else if (first_unusable.empty()) {
      first_unusable = "LED " + std::to_string(k) + ": " + summary.leds[k].note;
    }
  }
  timer.Finish(&summary);
  const int unusable = static_cast<int>(frames.size()) - summary.usable;
  if (unusable > 0)
    summary.End(core::Termination::kFailure,
                std::to_string(unusable) + " of " + std::to_string(frames.size()) + " LEDs unusable; " + first_unusable);
  else
    summary.End(core::Termination::kSuccess, "");
  return summary;
}

}  // namespace photorig::solvers::lighting
