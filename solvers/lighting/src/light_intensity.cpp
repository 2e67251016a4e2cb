#include "photorig/solvers/lighting/light_intensity.h"

#include <cmath>

namespace photorig::solvers::lighting {

bool DiffuseIntensityOptions::IsValid(std::string* why) const {
  if (!(albedo > 0.0) || !(min_cosine >= 0.0 && min_cosine < 1.0) ||
      !(max_radius_fraction > 0.0 && max_radius_fraction <= 1.0) || min_samples < 1) {
    if (why) *why = "albedo > 0, min_cosine in [0,1), max_radius_fraction in (0,1], min_samples >= 1";
    return false;
  }
  return true;
}

namespace {

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
      ++estimate.samples_used;
    }
  }
  if (estimate.samples_used < options.min_samples) {
    estimate.note = "too few lit, unsaturated samples (" + std::to_string(estimate.samples_used) + ")";
    return estimate;
  }
  estimate.rgb = sum_is / sum_ss;
  // SSE = sum I^2 - E^2 sum s^2 at the optimum.
  const double sse = std::max(0.0, (sum_ii - estimate.rgb.cwiseProduct(estimate.rgb) * sum_ss).sum());
  const double mean = (estimate.rgb.sum() / 3.0) * std::sqrt(sum_ss / estimate.samples_used);
  estimate.relative_rms_residual = std::sqrt(sse / (3.0 * estimate.samples_used)) / std::max(mean, 1e-12);
  estimate.usable = estimate.rgb.minCoeff() > 0.0;
  estimate.note = estimate.usable ? "fitted" : "non-positive intensity";
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
