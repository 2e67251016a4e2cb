#include "photorig/solvers/lighting/light_intensity.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

namespace photorig::solvers::lighting {

bool DiffuseIntensityOptions::IsValid(std::string* why) const {
  if (!(albedo > 0.0) || !(min_cosine >= 0.0 && min_cosine < 1.0) ||
      !(max_radius_fraction > 0.0 && max_radius_fraction <= 1.0) || min_samples < 1 || !(max_model_error > 0.0)) {
    if (why)
      *why = "albedo > 0, min_cosine in [0,1), max_radius_fraction in (0,1], min_samples >= 1, max_model_error > 0";
    return false;
  }
  return true;
}

namespace {

// Below this many adjacent pairs the noise estimate is left untested.
constexpr int kMinNoisePairs = 50;

// One sample the fit uses: its pixel, s = albedo / pi (n . l) and its RGB values.
struct IntensitySample {
  int column = 0, row = 0;
  double s = 0.0;
  Eigen::Vector3d rgb;
};

// A channel's noise variance and the variance of that estimate.
struct NoiseEstimate {
  double variance = std::numeric_limits<double>::quiet_NaN();
  double estimate_variance = 0.0;
};

// The noise variance of channel `channel` from the differences of the
// residuals e = I - E s between horizontally adjacent samples: Var(d) =
// 2 sigma^2 where the noise is independent from pixel to pixel, while shading
// the fit misses, smooth over a pixel, cancels. A shadow's or highlight's
// edge gives a few large differences: the mean of d^2 is taken over those
// within five robust (MAD) sigmas of zero, which keeps all but 6e-7 of a
// Gaussian's. NaN with fewer than kMinNoisePairs pairs.
NoiseEstimate EstimateNoise(const std::vector<IntensitySample>& samples, double irradiance, int channel) {
  std::vector<double> differences;
  for (std::size_t i = 1; i < samples.size(); ++i) {
    const IntensitySample &a = samples[i - 1], &b = samples[i];
    if (a.row != b.row || b.column != a.column + 1) continue;
    differences.push_back((b.rgb(channel) - irradiance * b.s) - (a.rgb(channel) - irradiance * a.s));
  }
  NoiseEstimate noise;
  if (static_cast<int>(differences.size()) < kMinNoisePairs) return noise;
  std::vector<double> magnitudes(differences.size());
  for (std::size_t i = 0; i < differences.size(); ++i) magnitudes[i] = std::abs(differences[i]);
  auto middle = magnitudes.begin() + static_cast<std::ptrdiff_t>(magnitudes.size() / 2);
  std::nth_element(magnitudes.begin(), middle, magnitudes.end());
  const double limit = 5.0 * 1.4826 * *middle;
  double sum = 0.0, sum_squares = 0.0;
  int count = 0;
  for (const double d : differences) {
    if (std::abs(d) > limit) continue;
    const double half_square = 0.5 * d * d;
    sum += half_square;
    sum_squares += half_square * half_square;
    ++count;
  }
  if (count == 0) return {0.0, 0.0};
  noise.variance = sum / count;
  noise.estimate_variance = std::max(0.0, sum_squares / count - noise.variance * noise.variance) / count;
  return noise;
}

// Least squares E_c = sum(I_c s) / sum(s^2) with s = albedo / pi * (n . l), per channel,
// over the samples `normal_at` yields.
template <typename NormalAt>
LightIntensityEstimate FitIntensity(const cv::Mat& image, const Eigen::Vector3d& light,
                                    const DiffuseIntensityOptions& options, NormalAt normal_at) {
  LightIntensityEstimate estimate;
  std::string why;
  if (!options.IsValid(&why)) {
    estimate.note = "invalid options: " + why;
    return estimate;
  }
  if (image.empty() || (image.channels() != 1 && image.channels() != 3)) {
    estimate.note = "intensity fit needs a 1- or 3-channel image";
    return estimate;
  }
  cv::Mat values;
  image.convertTo(values, CV_MAKETYPE(CV_32F, image.channels()));
  const int channels = values.channels();
  const Eigen::Vector3d l = light.normalized();
  Eigen::Vector3d sum_is = Eigen::Vector3d::Zero(), sum_ii = Eigen::Vector3d::Zero();
  double sum_ss = 0.0;
  std::vector<IntensitySample> samples;  // in raster order
  Eigen::Vector3d n;
  for (int r = 0; r < values.rows; ++r) {
    const float* row = values.ptr<float>(r);
    for (int c = 0; c < values.cols; ++c) {
      if (!normal_at(c, r, &n)) continue;
      const double s = options.albedo / M_PI * n.dot(l);
      if (s < options.albedo / M_PI * options.min_cosine) continue;
      Eigen::Vector3d rgb;
      bool clipped = false;
      for (int k = 0; k < 3; ++k) {
        // BGR storage -> RGB output; a grey image fills all three.
        const double v = channels == 1 ? row[c] : row[c * 3 + (2 - k)];
        clipped = clipped || (options.saturation_level >= 0.0 && v >= options.saturation_level);
        rgb(k) = v;
      }
      if (clipped) {
        ++estimate.samples_saturated;
        continue;
      }
      sum_is += rgb * s;
      sum_ii += rgb.cwiseProduct(rgb);
      sum_ss += s * s;
      samples.push_back({c, r, s, rgb});
      ++estimate.samples_used;
    }
  }
  if (estimate.samples_used < options.min_samples) {
    estimate.note = "too few lit, unsaturated samples (" + std::to_string(estimate.samples_used) + ")";
    return estimate;
  }
  estimate.rgb = sum_is / sum_ss;
  if (!(estimate.rgb.minCoeff() > 0.0)) {
    estimate.note = "non-positive intensity";
    return estimate;
  }
  // SSE = sum I^2 - E^2 sum s^2 at the optimum, per channel.
  const double n_used = estimate.samples_used;
  const double rms_s = std::sqrt(sum_ss / n_used);
  const Eigen::Vector3d sse = (sum_ii - estimate.rgb.cwiseProduct(estimate.rgb) * sum_ss).cwiseMax(0.0);
  const double mean = (estimate.rgb.sum() / 3.0) * rms_s;
  estimate.relative_rms_residual = std::sqrt(sse.sum() / (3.0 * n_used)) / std::max(mean, 1e-12);
  // A grey image repeats one channel three times: one test is enough.
  for (int k = 0; k < (channels == 1 ? 1 : 3); ++k) {
    const NoiseEstimate noise = EstimateNoise(samples, estimate.rgb(k), k);
    if (std::isnan(noise.variance)) {
      estimate.relative_noise_rms = estimate.model_error = std::numeric_limits<double>::quiet_NaN();
      break;
    }
    // The residuals' mean square beyond the noise, less three standard errors
    // of the two estimates: in a dim frame the residuals are nearly all noise,
    // and the difference of two estimates of it is their scatter, not shading.
    double sum_e4 = 0.0;
    for (const IntensitySample& sample : samples) {
      const double e = sample.rgb(k) - estimate.rgb(k) * sample.s;
      sum_e4 += e * e * e * e;
    }
    const double mse = sse(k) / n_used;
    const double mse_variance = std::max(0.0, sum_e4 / n_used - mse * mse) / n_used;
    const double excess = mse - noise.variance - 3.0 * std::sqrt(mse_variance + noise.estimate_variance);
    const double channel_mean = estimate.rgb(k) * rms_s;
    estimate.relative_noise_rms = std::max(estimate.relative_noise_rms, std::sqrt(noise.variance) / channel_mean);
    estimate.model_error = std::max(estimate.model_error, std::sqrt(std::max(0.0, excess)) / channel_mean);
  }
  if (estimate.model_error > options.max_model_error) {
    char text[360];
    std::snprintf(text, sizeof(text),
                  "the target's shading departs from a matte surface's by %.1f %% of the mean sample beyond its noise "
                  "(%.1f %%; at most %.1f %%): a glossy or shadowed target, an interreflection, a black level left "
                  "in the image, or a target that is not where its geometry says",
                  100.0 * estimate.model_error, 100.0 * estimate.relative_noise_rms, 100.0 * options.max_model_error);
    estimate.note = text;
    return estimate;
  }
  estimate.usable = true;
  estimate.note = std::isnan(estimate.model_error) ? "fitted; too few adjacent samples to test its shading" : "fitted";
  return estimate;
}

}  // namespace

LightIntensityEstimate EstimateIntensityFromSphere(const cv::Mat& image, const SphereGeometry& sphere,
                                                   const Eigen::Vector3d& light_direction,
                                                   const DiffuseIntensityOptions& options) {
  if (!sphere.valid) {
    LightIntensityEstimate estimate;
    estimate.note = "sphere not located: " + sphere.message;
    return estimate;
  }
  const double limit = options.max_radius_fraction * sphere.circle.radius_px;
  return FitIntensity(image, light_direction, options, [&](int c, int r, Eigen::Vector3d* n) {
    const double du = c - sphere.circle.cx_px, dv = r - sphere.circle.cy_px;
    if (du * du + dv * dv > limit * limit) return false;
    SurfacePoint point;
    if (!SurfaceAt(sphere, c, r, &point)) return false;
    *n = point.normal;
    return true;
  });
}

LightIntensityEstimate EstimateIntensityFromPlane(const cv::Mat& image, const cv::Mat& mask,
                                                  const Eigen::Vector3d& plane_normal,
                                                  const Eigen::Vector3d& light_direction,
                                                  const DiffuseIntensityOptions& options) {
  if (!mask.empty() && (mask.size() != image.size() || mask.type() != CV_8U)) {
    LightIntensityEstimate estimate;
    estimate.note = "mask must be CV_8U of the image size";
    return estimate;
  }
  const Eigen::Vector3d normal = plane_normal.normalized();
  return FitIntensity(image, light_direction, options, [&](int c, int r, Eigen::Vector3d* n) {
    if (!mask.empty() && !mask.at<std::uint8_t>(r, c)) return false;
    *n = normal;
    return true;
  });
}

void NormaliseIntensities(std::vector<LightIntensityEstimate>* estimates) {
  double sum = 0.0;
  int count = 0;
  for (const auto& e : *estimates) {
    if (!e.usable) continue;
    sum += e.rgb.sum();
    count += 3;
  }
  if (count == 0) return;
  const double mean = sum / count;
  for (auto& e : *estimates) {
    if (e.usable) e.rgb /= mean;
  }
}

}  // namespace photorig::solvers::lighting
