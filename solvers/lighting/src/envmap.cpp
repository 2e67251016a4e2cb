#include "photorig/solvers/lighting/envmap.h"

#include "photorig/solvers/lighting/spherical_harmonics.h"

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <string>
#include <utility>

namespace photorig::solvers::lighting {

Eigen::Vector3d LatLongDirection(double u, double v, int width, int height) {
  const double theta = M_PI * (v + 0.5) / height;
  const double phi = 2.0 * M_PI * (u + 0.5) / width - M_PI;
  return {std::sin(theta) * std::sin(phi), std::cos(theta), std::sin(theta) * std::cos(phi)};
}

Eigen::Vector2d LatLongPixel(const Eigen::Vector3d& direction, int width, int height) {
  const Eigen::Vector3d d = direction.normalized();
  const double theta = std::acos(std::clamp(d.y(), -1.0, 1.0));
  const double phi = std::atan2(d.x(), d.z());
  return {(phi + M_PI) / (2.0 * M_PI) * width - 0.5, theta / M_PI * height - 0.5};
}

bool UnwrapOptions::IsValid(std::string* why) const {
  if (width < 4 || width % 2 != 0) {
    if (why) *why = "width must be even and >= 4, got " + std::to_string(width);
    return false;
  }
  if (!(blind_cone_deg >= 0.0 && blind_cone_deg < 90.0)) {
    if (why) *why = "blind_cone_deg must be in [0, 90), got " + std::to_string(blind_cone_deg);
    return false;
  }
  return true;
}

bool ExposureMergeOptions::IsValid(std::string* why) const {
  if (!(saturation_level > black_level)) {
    if (why) *why = "saturation_level must exceed black_level";
    return false;
  }
  return true;
}

namespace {

using solvers::core::Ended;
using solvers::core::Termination;

bool IsLatLong(const cv::Mat& map) { return !map.empty() && map.cols == 2 * map.rows; }

}  // namespace

solvers::core::Summary MirrorBallToLatLong(const cv::Mat& ball_image, const SphereGeometry& sphere,
                                     const UnwrapOptions& options, LatLongMap* map) {
  const solvers::core::SolveTimer timer;
  std::string why;
  if (!options.IsValid(&why)) return Ended(Termination::kInvalidOptions, "invalid options: " + why);
  if (!sphere.valid || sphere.camera.projection != CameraModel::Projection::kOrthographic) {
    return Ended(Termination::kInvalidInput, "needs a located sphere seen by an orthographic camera");
  }
  if (ball_image.empty()) return Ended(Termination::kInvalidInput, "the mirror-ball image is empty");
  const int width = options.width, height = options.width / 2;
  cv::Mat map_u(height, width, CV_32F), map_v(height, width, CV_32F);
  LatLongMap result;
  result.valid = cv::Mat(height, width, CV_8U, cv::Scalar(0));
  const double blind_cos = -std::cos(options.blind_cone_deg * M_PI / 180.0);
  const Circle& c = sphere.circle;
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const Eigen::Vector3d d = LatLongDirection(u, v, width, height);
      float pu = -1.0f, pv = -1.0f;
      if (d.z() > blind_cos) {
        // The normal halfway between the view vector (0, 0, 1) and d reflects one into the other.
        const Eigen::Vector3d n = (d + Eigen::Vector3d::UnitZ()).normalized();
        pu = static_cast<float>(c.cx_px + c.radius_px * n.x());
        pv = static_cast<float>(c.cy_px - c.radius_px * n.y());
        result.valid.at<std::uint8_t>(v, u) = 255;
      }
      map_u.at<float>(v, u) = pu;
      map_v.at<float>(v, u) = pv;
    }
  }
  cv::Mat source;
  ball_image.convertTo(source, CV_MAKETYPE(CV_32F, ball_image.channels()));
  cv::remap(source, result.radiance, map_u, map_v, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar::all(0));
  *map = std::move(result);
  return timer.Succeeded();
}

solvers::core::Summary LatLongToMirrorBall(const cv::Mat& latlong, int size_px, cv::Mat* ball) {
  const solvers::core::SolveTimer timer;
  if (!IsLatLong(latlong)) return Ended(Termination::kInvalidInput, "needs a 2:1 lat-long map");
  if (size_px < 2) {
    return Ended(Termination::kInvalidInput, "ball size must be >= 2 px, got " + std::to_string(size_px));
  }
  cv::Mat source;
  latlong.convertTo(source, CV_MAKETYPE(CV_32F, latlong.channels()));
  // One column of wrap-around on each side so that bilinear sampling crosses the seam.
  cv::copyMakeBorder(source, source, 0, 0, 1, 1, cv::BORDER_WRAP);
  const double centre = (size_px - 1) / 2.0, radius = size_px / 2.0;
  cv::Mat map_u(size_px, size_px, CV_32F, cv::Scalar(-10)), map_v(size_px, size_px, CV_32F, cv::Scalar(-10));
  for (int v = 0; v < size_px; ++v) {
    for (int u = 0; u < size_px; ++u) {
      const double x = (u - centre) / radius, y = -(v - centre) / radius;
      const double rho2 = x * x + y * y;
      if (rho2 > 1.0) continue;
      const Eigen::Vector3d n(x, y, std::sqrt(1.0 - rho2));
      const Eigen::Vector3d d = 2.0 * n.z() * n - Eigen::Vector3d::UnitZ();
      const Eigen::Vector2d p = LatLongPixel(d, latlong.cols, latlong.rows);
      map_u.at<float>(v, u) = static_cast<float>(p.x() + 1.0);
      map_v.at<float>(v, u) = static_cast<float>(std::clamp(p.y(), 0.0, latlong.rows - 1.0));
    }
  }
  cv::remap(source, *ball, map_u, map_v, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar::all(0));
  return timer.Succeeded();
}

solvers::core::Summary MergeExposures(const std::vector<cv::Mat>& frames, const std::vector<double>& exposure_us,
                                const ExposureMergeOptions& options, HdrMerge* merge_out) {
  const solvers::core::SolveTimer timer;
  std::string why;
  if (!options.IsValid(&why)) return Ended(Termination::kInvalidOptions, "invalid options: " + why);
  if (frames.empty() || frames.size() != exposure_us.size()) {
    return Ended(Termination::kInvalidInput, std::to_string(frames.size()) + " frames for " +
                                                          std::to_string(exposure_us.size()) + " exposures");
  }
  const double span = options.saturation_level - options.black_level;
  std::size_t shortest = 0;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    if (frames[k].empty() || frames[k].size() != frames[0].size() || frames[k].type() != frames[0].type()) {
      return Ended(Termination::kInvalidInput,
                   "frame " + std::to_string(k) + " differs from frame 0 in size or type (or is empty)");
    }
    if (!(exposure_us[k] > 0.0)) {
      return Ended(Termination::kInvalidInput,
                   "exposure " + std::to_string(k) + " is not positive: " + std::to_string(exposure_us[k]) + " us");
    }
    if (exposure_us[k] < exposure_us[shortest]) shortest = k;
  }
  const int type = CV_MAKETYPE(CV_32F, frames[0].channels());
  cv::Mat sum = cv::Mat::zeros(frames[0].size(), type), weights = cv::Mat::zeros(frames[0].size(), type);
  cv::Mat value, weight;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    frames[k].convertTo(value, type);
    value -= cv::Scalar::all(options.black_level);
    // Hat weight: trust mid-range values, none at black or clipping.
    cv::min(value, cv::Scalar::all(span) - value, weight);
    cv::max(weight, 0.0, weight);
    weight.setTo(0.0, value >= span * 0.999);
    cv::accumulateProduct(weight, value * (1.0 / exposure_us[k]), sum);
    weights += weight;
  }
  HdrMerge merge;
  cv::divide(sum, weights, merge.radiance);
  // Pixels no exposure resolved take the shortest exposure's value, clipped, and are flagged.
  cv::Mat fallback;
  frames[shortest].convertTo(fallback, type, 1.0 / exposure_us[shortest], -options.black_level / exposure_us[shortest]);
  cv::Mat unresolved = weights <= 0.0;
  if (unresolved.channels() > 1) {
    std::vector<cv::Mat> planes;
    cv::split(unresolved, planes);
    unresolved = planes[0];
    for (std::size_t i = 1; i < planes.size(); ++i) unresolved |= planes[i];
  }
  fallback.copyTo(merge.radiance, unresolved);
  merge.unresolved = unresolved;
  merge.unresolved_pixels = cv::countNonZero(unresolved);
  *merge_out = std::move(merge);
  if (merge_out->unresolved_pixels == 0) return timer.Succeeded();
  return timer.Succeeded(std::to_string(merge_out->unresolved_pixels) +
                              " pixels saturated in every exposure (clipped values from the shortest; flagged)");
}

namespace {

// Solid angle of one lat-long pixel at row v.
double PixelSolidAngle(int v, int width, int height) {
  const double theta0 = M_PI * v / height, theta1 = M_PI * (v + 1) / height;
  return 2.0 * M_PI / width * (std::cos(theta0) - std::cos(theta1));
}

}  // namespace

solvers::core::Summary ProjectLatLongToSh(const cv::Mat& latlong, int band, Eigen::MatrixXd* coefficients_out) {
  const solvers::core::SolveTimer timer;
  if (band < 0 || band > 8) {
    return Ended(Termination::kInvalidOptions, "band must be in [0, 8], got " + std::to_string(band));
  }
  if (!IsLatLong(latlong)) return Ended(Termination::kInvalidInput, "needs a 2:1 lat-long map");
  cv::Mat source;
  latlong.convertTo(source, CV_MAKETYPE(CV_32F, latlong.channels()));
  const int channels = source.channels();
  Eigen::MatrixXd coefficients = Eigen::MatrixXd::Zero(ShCoefficientCount(band), channels);
  Eigen::VectorXd y(ShCoefficientCount(band));
  for (int v = 0; v < source.rows; ++v) {
    const double d_omega = PixelSolidAngle(v, source.cols, source.rows);
    const float* row = source.ptr<float>(v);
    for (int u = 0; u < source.cols; ++u) {
      EvaluateSh(band, LatLongDirection(u, v, source.cols, source.rows), y.data());
      for (int ch = 0; ch < channels; ++ch) {
        coefficients.col(channels == 3 ? 2 - ch : 0) += (row[u * channels + ch] * d_omega) * y;
      }
    }
  }
  *coefficients_out = std::move(coefficients);
  return timer.Succeeded();
}

solvers::core::Summary LatLongToLedWeights(const cv::Mat& latlong, const std::vector<Eigen::Vector3d>& led_directions,
                                     const std::vector<double>& led_intensities, Eigen::MatrixXd* weights_out) {
  const solvers::core::SolveTimer timer;
  if (!IsLatLong(latlong)) return Ended(Termination::kInvalidInput, "needs a 2:1 lat-long map");
  if (led_directions.empty() || led_directions.size() != led_intensities.size()) {
    return Ended(Termination::kInvalidInput, std::to_string(led_directions.size()) + " LED directions for " +
                                                          std::to_string(led_intensities.size()) + " intensities");
  }
  for (std::size_t k = 0; k < led_intensities.size(); ++k) {
    if (!(led_intensities[k] > 0.0) || !(led_directions[k].norm() > 0.0)) {
      return Ended(Termination::kInvalidInput,
                   "LED " + std::to_string(k) + " has a non-positive intensity or a zero direction");
    }
  }
  cv::Mat source;
  latlong.convertTo(source, CV_MAKETYPE(CV_32F, latlong.channels()));
  const int channels = source.channels();
  Eigen::MatrixXd weights = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(led_directions.size()), channels);
  for (int v = 0; v < source.rows; ++v) {
    const double d_omega = PixelSolidAngle(v, source.cols, source.rows);
    const float* row = source.ptr<float>(v);
    for (int u = 0; u < source.cols; ++u) {
      const Eigen::Vector3d d = LatLongDirection(u, v, source.cols, source.rows);
      if (d.z() <= 0.0) continue;
      Eigen::Index nearest = 0;
      double best = -2.0;
      for (std::size_t k = 0; k < led_directions.size(); ++k) {
        const double cosine = d.dot(led_directions[k].normalized());
        if (cosine > best) {
          best = cosine;
          nearest = static_cast<Eigen::Index>(k);
        }
      }
      for (int ch = 0; ch < channels; ++ch) {
        weights(nearest, channels == 3 ? 2 - ch : 0) += row[u * channels + ch] * d_omega;
      }
    }
  }
  for (std::size_t k = 0; k < led_intensities.size(); ++k) weights.row(static_cast<Eigen::Index>(k)) /= led_intensities[k];
  *weights_out = std::move(weights);
  return timer.Succeeded();
}

}  // namespace photorig::solvers::lighting
