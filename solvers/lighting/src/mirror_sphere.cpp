#include "photorig/solvers/lighting/mirror_sphere.h"

#include "photorig/solvers/core/flags.h"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace photorig::solvers::lighting {

std::string LightFlagsToString(unsigned flags) {
  static constexpr std::array<std::pair<unsigned, const char*>, 6> kNames = {
      {{kLightSaturated, "saturated"},
       {kLightNearSilhouette, "near-silhouette"},
       {kLightMissing, "missing"},
       {kLightMultipleHighlights, "multiple-highlights"},
       {kLightLargeHighlight, "large-highlight"},
       {kLightUncertain, "uncertain"}}};
  return core::FlagNames(flags, kNames);
}

bool HighlightOptions::IsValid(std::string* why) const {
  if (!(threshold_fraction > 0.0 && threshold_fraction < 1.0) || !(min_peak_sigma > 0.0) ||
      !(silhouette_margin_deg >= 0.0 && silhouette_margin_deg < 90.0) || !(max_blob_fraction > 0.0) ||
      !(max_uncertainty_deg > 0.0)) {
    if (why) *why = "threshold_fraction in (0,1), min_peak_sigma > 0, silhouette_margin_deg in [0,90), "
                    "max_blob_fraction > 0, max_uncertainty_deg > 0";
    return false;
  }
  return true;
}

namespace {

// The highlight's blob: the 8-connected pixels at or above the threshold
// reached from the peak, and the pixels on the sphere above it elsewhere.
struct Blob {
  Eigen::Vector2d centroid_px = Eigen::Vector2d::Zero();
  int area = 0;
  bool touches_rim = false;  // reaches the image's edge or the sphere's silhouette
  int stray = 0;             // pixels on the sphere within `window` above the threshold, outside the blob
};

Blob GrowBlob(const cv::Mat& values, const cv::Mat& on_sphere, cv::Point peak_at, double threshold, bool saturated,
              const cv::Rect& window) {
  cv::Mat in_blob(values.size(), CV_8U, cv::Scalar(0));
  std::vector<cv::Point> stack{peak_at};
  in_blob.at<std::uint8_t>(peak_at) = 1;
  Blob blob;
  double weight_sum = 0.0, su = 0.0, sv = 0.0;
  while (!stack.empty()) {
    const cv::Point p = stack.back();
    stack.pop_back();
    const double value = values.at<float>(p);
    // Saturated blob: plain centroid (the clipped values carry no shape); otherwise intensity-weighted.
    const double weight = saturated ? 1.0 : value - threshold + 1e-12;
    weight_sum += weight;
    su += weight * p.x;
    sv += weight * p.y;
    ++blob.area;
    for (int dr = -1; dr <= 1; ++dr) {
      for (int dc = -1; dc <= 1; ++dc) {
        const cv::Point q(p.x + dc, p.y + dr);
        if (q.x < 0 || q.y < 0 || q.x >= values.cols || q.y >= values.rows) {
          blob.touches_rim = true;
          continue;
        }
        if (!on_sphere.at<std::uint8_t>(q)) {
          blob.touches_rim = true;
          continue;
        }
        if (in_blob.at<std::uint8_t>(q) || values.at<float>(q) < threshold) continue;
        in_blob.at<std::uint8_t>(q) = 1;
        stack.push_back(q);
      }
    }
  }
  for (int r = window.y; r < window.y + window.height; ++r) {
    for (int col = window.x; col < window.x + window.width; ++col) {
      if (on_sphere.at<std::uint8_t>(r, col) && !in_blob.at<std::uint8_t>(r, col) &&
          values.at<float>(r, col) >= threshold) {
        ++blob.stray;
      }
    }
  }
  blob.centroid_px = {su / weight_sum, sv / weight_sum};
  return blob;
}

}  // namespace

LightDirectionEstimate EstimateLightDirection(const cv::Mat& image, const SphereGeometry& sphere,
                                              const HighlightOptions& options) {
  LightDirectionEstimate estimate;
  std::string why;
  if (!options.IsValid(&why)) {
    estimate.note = "invalid options: " + why;
    estimate.flags = kLightMissing;
    return estimate;
  }
  if (!sphere.valid || image.empty() || image.channels() != 1) {
    estimate.note = sphere.valid ? "highlight search needs a single-channel image" : "sphere not located: " + sphere.message;
    estimate.flags = kLightMissing;
    return estimate;
  }
  cv::Mat values;
  image.convertTo(values, CV_32F);

  // Pixels on the sphere (the image circle bounds the search for both camera models).
  const Circle& c = sphere.circle;
  const int r0 = std::max(0, static_cast<int>(std::floor(c.cy_px - c.radius_px - 1)));
  const int r1 = std::min(values.rows - 1, static_cast<int>(std::ceil(c.cy_px + c.radius_px + 1)));
  const int c0 = std::max(0, static_cast<int>(std::floor(c.cx_px - c.radius_px - 1)));
  const int c1 = std::min(values.cols - 1, static_cast<int>(std::ceil(c.cx_px + c.radius_px + 1)));
  cv::Mat on_sphere(values.size(), CV_8U, cv::Scalar(0));
  std::vector<float> samples;
  SurfacePoint point;
  float peak = -1.0f;
  cv::Point peak_at(-1, -1);
  int peak_count = 0;
  for (int r = r0; r <= r1; ++r) {
    for (int col = c0; col <= c1; ++col) {
      if (!SurfaceAt(sphere, col, r, &point)) continue;
      on_sphere.at<std::uint8_t>(r, col) = 1;
      const float value = values.at<float>(r, col);
      samples.push_back(value);
      if (value > peak) {
        peak = value;
        peak_at = {col, r};
        peak_count = 1;
      } else if (value == peak) {
        ++peak_count;
      }
    }
  }
  if (samples.size() < 16) {
    estimate.flags = kLightMissing;
    estimate.note = "sphere has too few pixels in the image";
    return estimate;
  }
  const auto mid = samples.begin() + static_cast<std::ptrdiff_t>(samples.size() / 2);
  std::nth_element(samples.begin(), mid, samples.end());
  const double background = *mid;
  for (float& s : samples) s = std::abs(s - static_cast<float>(background));
  std::nth_element(samples.begin(), mid, samples.end());
  const double noise = std::max(1.4826 * *mid, 1e-6 * std::max(1.0, std::abs(background)));
  estimate.peak = peak;
  if (peak - background < options.min_peak_sigma * noise) {
    estimate.flags = kLightMissing;
    estimate.note = "no highlight above background noise";
    return estimate;
  }

  const double saturation = options.saturation_level >= 0.0 ? options.saturation_level
                                                            : (peak_count >= 3 ? static_cast<double>(peak) : HUGE_VAL);
  const bool saturated = peak >= saturation;
  const double threshold =
      saturated ? saturation : background + options.threshold_fraction * (peak - background);
  if (saturated) estimate.flags |= kLightSaturated;

  const cv::Rect window(c0, r0, c1 - c0 + 1, r1 - r0 + 1);
  const Blob blob = GrowBlob(values, on_sphere, peak_at, threshold, saturated, window);
  const int area = blob.area;
  if (blob.stray > std::max(2, area / 4)) estimate.flags |= kLightMultipleHighlights;

  estimate.highlight_px = blob.centroid_px;
  estimate.blob_area_px = area;
  const double disc_area = M_PI * c.radius_px * c.radius_px;
  if (area > options.max_blob_fraction * disc_area) estimate.flags |= kLightLargeHighlight;

  if (!SurfaceAt(sphere, estimate.highlight_px.x(), estimate.highlight_px.y(), &point)) {
    // A centroid can fall just outside a thin crescent at the rim.
    estimate.flags |= kLightNearSilhouette;
    estimate.note = "highlight centroid off the sphere";
    return estimate;
  }
  const Eigen::Vector3d& n = point.normal;
  const Eigen::Vector3d& w_o = point.to_camera;
  estimate.normal = n;
  estimate.surface_position = point.position;
  estimate.direction = (2.0 * w_o.dot(n) * n - w_o).normalized();

  const double cos_normal = std::clamp(w_o.dot(n), 1e-6, 1.0);
  const double sin_normal = std::sqrt(1.0 - cos_normal * cos_normal);
  if (blob.touches_rim || cos_normal < std::sin(options.silhouette_margin_deg * M_PI / 180.0)) {
    estimate.flags |= kLightNearSilhouette;
  }
  // Centroid error: quantisation over the blob plus a blob-size share that grows
  // towards the rim, where the sphere foreshortens the blob asymmetrically.
  const double blob_radius = std::sqrt(area / M_PI);
  const double sigma_px = 0.29 / std::sqrt(static_cast<double>(area)) + 0.1 * blob_radius * sin_normal;
  // The normal turns by d(rho) / cos(theta_n) per unit of radius; the reflection doubles it.
  estimate.uncertainty_deg = 2.0 * sigma_px / (c.radius_px * cos_normal) * 180.0 / M_PI;
  if (estimate.uncertainty_deg > options.max_uncertainty_deg) estimate.flags |= kLightUncertain;

  estimate.usable = !(estimate.flags & (kLightMissing | kLightMultipleHighlights | kLightNearSilhouette));
  estimate.note = LightFlagsToString(estimate.flags);
  return estimate;
}

bool HighlightCircleOptions::IsValid(std::string* why) const {
  if (!highlight.IsValid(why)) return false;
  if (!(fixed_radius_px >= 0.0) || !(outlier_px > 0.0) || min_highlights < 2) {
    if (why) *why = "fixed_radius_px >= 0, outlier_px > 0, min_highlights >= 2";
    return false;
  }
  return true;
}

HighlightCircleSummary LocateSphereFromHighlights(const std::vector<cv::Mat>& frames,
                                                  const std::vector<Eigen::Vector3d>& nominal_directions,
                                                  const HighlightCircleOptions& options) {
  const solvers::core::SolveTimer timer;
  HighlightCircleSummary summary;
  if (solvers::core::EndIfInvalid(options, &summary)) return summary;
  if (frames.size() != nominal_directions.size()) {
    summary.termination = solvers::core::Termination::kInvalidInput;
    summary.message = std::to_string(frames.size()) + " frames for " + std::to_string(nominal_directions.size()) +
                      " nominal light directions";
    return summary;
  }
  struct Observation {
    int frame;
    Eigen::Vector2d highlight_px;
    Eigen::Vector2d half_xy;  // (h_x, -h_y): the image offset per unit radius
  };
  std::vector<Observation> observations;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    if (frames[k].empty()) {
      summary.rejected.push_back(static_cast<int>(k));
      continue;
    }
    // The highlight search of EstimateLightDirection, bounded by a circle
    // around the whole frame; only its highlight position is used here.
    SphereGeometry whole_frame;
    whole_frame.valid = true;
    whole_frame.circle = {0.5 * (frames[k].cols - 1), 0.5 * (frames[k].rows - 1),
                          0.5 * std::hypot(frames[k].cols, frames[k].rows) + 2.0};
    const LightDirectionEstimate found = EstimateLightDirection(frames[k], whole_frame, options.highlight);
    const Eigen::Vector3d half = (nominal_directions[k].normalized() + Eigen::Vector3d::UnitZ()).normalized();
    if ((found.flags & (kLightMissing | kLightMultipleHighlights)) || !half.allFinite()) {
      summary.rejected.push_back(static_cast<int>(k));
      continue;
    }
    observations.push_back({static_cast<int>(k), found.highlight_px, Eigen::Vector2d(half.x(), -half.y())});
  }

  const bool fit_radius = options.fixed_radius_px == 0.0;
  auto fit = [&](const std::vector<Observation>& used) {
    const int unknowns = fit_radius ? 3 : 2;
    Eigen::MatrixXd a = Eigen::MatrixXd::Zero(2 * static_cast<Eigen::Index>(used.size()), unknowns);
    Eigen::VectorXd b(2 * static_cast<Eigen::Index>(used.size()));
    for (std::size_t i = 0; i < used.size(); ++i) {
      for (int axis = 0; axis < 2; ++axis) {
        const Eigen::Index row = 2 * static_cast<Eigen::Index>(i) + axis;
        a(row, axis) = 1.0;
        b(row) = used[i].highlight_px[axis];
        if (fit_radius) a(row, 2) = used[i].half_xy[axis];
        else b(row) -= options.fixed_radius_px * used[i].half_xy[axis];
      }
    }
    const Eigen::VectorXd x = a.colPivHouseholderQr().solve(b);
    return Circle{x(0), x(1), fit_radius ? x(2) : options.fixed_radius_px};
  };
  auto residual_px = [](const Circle& c, const Observation& o) {
    return (o.highlight_px - Eigen::Vector2d(c.cx_px, c.cy_px) - c.radius_px * o.half_xy).norm();
  };

  if (static_cast<int>(observations.size()) < options.min_highlights) {
    summary.termination = solvers::core::Termination::kFailure;
    summary.message = "only " + std::to_string(observations.size()) + " highlights found (need " +
                      std::to_string(options.min_highlights) + ")";
    return summary;
  }
  Circle circle = fit(observations);
  std::vector<Observation> kept;
  for (const Observation& o : observations) {
    if (residual_px(circle, o) <= options.outlier_px) kept.push_back(o);
    else summary.rejected.push_back(o.frame);
  }
  if (static_cast<int>(kept.size()) < options.min_highlights) {
    summary.termination = solvers::core::Termination::kFailure;
    summary.message = "the highlights do not fit one sphere under the nominal light directions (" +
                      std::to_string(kept.size()) + " of " + std::to_string(observations.size()) + " within " +
                      std::to_string(options.outlier_px) + " px)";
    return summary;
  }
  if (kept.size() != observations.size()) circle = fit(kept);
  double sum_squares = 0.0;
  for (const Observation& o : kept) sum_squares += std::pow(residual_px(circle, o), 2);
  std::sort(summary.rejected.begin(), summary.rejected.end());
  summary.circle = circle;
  summary.highlights_used = static_cast<int>(kept.size());
  summary.rms_residual_px = std::sqrt(sum_squares / static_cast<double>(kept.size()));
  if (!(circle.radius_px > 0.0)) {
    summary.termination = solvers::core::Termination::kFailure;
    summary.message = "the fitted radius is not positive: the nominal directions do not match the highlights";
    return summary;
  }
  summary.End(solvers::core::Termination::kSuccess, "sphere from " + std::to_string(kept.size()) + " highlights");
  timer.Finish(&summary);
  return summary;
}

NearLightEstimate TriangulateNearLight(const std::vector<Eigen::Vector3d>& origins_mm,
                                       const std::vector<Eigen::Vector3d>& directions) {
  NearLightEstimate result;
  if (origins_mm.size() != directions.size() || origins_mm.size() < 2) {
    result.message = "triangulation needs two or more rays";
    return result;
  }
  // Minimise sum |(I - d d^T)(x - o)|^2.
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < origins_mm.size(); ++i) {
    const Eigen::Vector3d d = directions[i].normalized();
    const Eigen::Matrix3d projector = Eigen::Matrix3d::Identity() - d * d.transpose();
    a += projector;
    b += projector * origins_mm[i];
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(a);
  const double conditioning = eigen.eigenvalues()(0) / eigen.eigenvalues()(2);
  if (conditioning < 1e-8) {
    result.message = "rays are parallel: the light is effectively distant";
    return result;
  }
  result.position_mm = a.ldlt().solve(b);
  double sum_squares = 0.0;
  for (std::size_t i = 0; i < origins_mm.size(); ++i) {
    const Eigen::Vector3d d = directions[i].normalized();
    const Eigen::Vector3d offset = result.position_mm - origins_mm[i];
    sum_squares += (offset - offset.dot(d) * d).squaredNorm();
    if (offset.dot(d) <= 0.0) result.message = "point lies behind a reflection ray";
  }
  result.rms_ray_distance_mm = std::sqrt(sum_squares / static_cast<double>(origins_mm.size()));
  result.usable = result.message.empty();
  if (result.usable) result.message = "triangulated";
  return result;
}

Eigen::Vector3d ReflectionPointMm(const SphereGeometry& sphere, const LightDirectionEstimate& estimate,
                                  double pixel_pitch_mm, double sphere_radius_mm) {
  if (sphere.camera.projection == CameraModel::Projection::kOrthographic) {
    const Eigen::Vector3d centre(sphere.circle.cx_px * pixel_pitch_mm, -sphere.circle.cy_px * pixel_pitch_mm, 0.0);
    return centre + sphere.circle.radius_px * pixel_pitch_mm * estimate.surface_position;
  }
  return sphere_radius_mm * estimate.surface_position;
}

}  // namespace photorig::solvers::lighting
