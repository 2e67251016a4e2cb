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

namespace {

// A map's texels of the upper hemisphere (z > 0): each one's direction and
// its radiance times its solid angle, per channel as R, G, B. Built once per
// map, since a near dome assigns them to LEDs once per grid point.
struct UpperTexels {
  int channels = 1;
  std::vector<Eigen::Vector3d> directions;
  std::vector<Eigen::Vector3d> light;  // radiance x solid angle; channels == 1: x only

  explicit UpperTexels(const cv::Mat& source) : channels(source.channels()) {
    for (int v = 0; v < source.rows; ++v) {
      const double d_omega = PixelSolidAngle(v, source.cols, source.rows);
      const float* row = source.ptr<float>(v);
      for (int u = 0; u < source.cols; ++u) {
        const Eigen::Vector3d d = LatLongDirection(u, v, source.cols, source.rows);
        if (d.z() <= 0.0) continue;
        directions.push_back(d);
        Eigen::Vector3d l = Eigen::Vector3d::Zero();
        for (int ch = 0; ch < channels; ++ch) l[channels == 3 ? 2 - ch : 0] = row[u * channels + ch] * d_omega;
        light.push_back(l);
      }
    }
  }
};

// Per LED (rows) and channel (R, G, B columns), the light of the texels
// nearer that LED than any other with reaches[k]. directions: unit vectors.
Eigen::MatrixXd NearestLedRadiance(const UpperTexels& texels, const std::vector<Eigen::Vector3d>& directions,
                                   const std::vector<char>& reaches) {
  Eigen::MatrixXd radiance = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(directions.size()), texels.channels);
  for (std::size_t t = 0; t < texels.directions.size(); ++t) {
    Eigen::Index nearest = -1;
    double best = -2.0;
    for (std::size_t k = 0; k < directions.size(); ++k) {
      const double cosine = texels.directions[t].dot(directions[k]);
      if (reaches[k] && cosine > best) {
        best = cosine;
        nearest = static_cast<Eigen::Index>(k);
      }
    }
    if (nearest >= 0) radiance.row(nearest) += texels.light[t].head(texels.channels).transpose();
  }
  return radiance;
}

// The grid positions along an axis of `size` pixels: every step-th, and the last.
std::vector<int> GridPositions(int size, int step) {
  std::vector<int> at;
  for (int v = 0; v < size; v += step) at.push_back(v);
  if (at.back() != size - 1) at.push_back(size - 1);
  return at;
}

// For each pixel along an axis, the grid position at or before it and its fraction of the way to the next.
void GridCells(const std::vector<int>& grid, int size, std::vector<int>* left, std::vector<float>* fraction) {
  left->resize(size), fraction->resize(size);
  std::size_t j = 0;
  for (int x = 0; x < size; ++x) {
    while (j + 2 < grid.size() && grid[j + 1] <= x) ++j;
    (*left)[x] = static_cast<int>(j);
    (*fraction)[x] = grid.size() < 2 ? 0.0f : static_cast<float>(x - grid[j]) / static_cast<float>(grid[j + 1] - grid[j]);
  }
}

}  // namespace

solvers::core::Summary LatLongToLedWeights(const cv::Mat& latlong, const std::vector<Eigen::Vector3d>& led_directions,
                                     const std::vector<double>& led_intensities, Eigen::MatrixXd* weights_out) {
  const solvers::core::SolveTimer timer;
  if (!IsLatLong(latlong) || (latlong.channels() != 1 && latlong.channels() != 3))
    return Ended(Termination::kInvalidInput, "needs a 2:1 lat-long map of 1 or 3 channels");
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
  std::vector<Eigen::Vector3d> directions;
  for (const Eigen::Vector3d& d : led_directions) directions.push_back(d.normalized());
  Eigen::MatrixXd weights = NearestLedRadiance(UpperTexels(source), directions, std::vector<char>(directions.size(), 1));
  for (std::size_t k = 0; k < led_intensities.size(); ++k) weights.row(static_cast<Eigen::Index>(k)) /= led_intensities[k];
  *weights_out = std::move(weights);
  return timer.Succeeded();
}

bool NearRelightOptions::IsValid(std::string* why) const {
  if (grid_px < 2) return solvers::core::Refuse(why, "grid_px must be at least 2, got " + std::to_string(grid_px));
  if (map_width_px < 2 || map_width_px % 2 != 0)
    return solvers::core::Refuse(why, "map_width_px must be even and at least 2, got " + std::to_string(map_width_px));
  return true;
}

solvers::core::Summary RelightNearFromEnvironment(const NearRelightOptions& options, const cv::Mat& latlong,
                                                  const std::vector<camera::NearLight>& leds,
                                                  const std::vector<double>& led_scales,
                                                  const std::vector<cv::Mat>& frames, const cv::Mat& points_mm,
                                                  cv::Mat* image) {
  solvers::core::SolveTimer timer;
  solvers::core::Summary summary;
  if (solvers::core::EndIfInvalid(options, &summary)) return summary;
  if (!IsLatLong(latlong) || (latlong.channels() != 1 && latlong.channels() != 3))
    return Ended(Termination::kInvalidInput, "needs a 2:1 lat-long map of 1 or 3 channels");
  if (leds.empty() || leds.size() != led_scales.size() || leds.size() != frames.size())
    return Ended(Termination::kInvalidInput, std::to_string(leds.size()) + " LEDs, " + std::to_string(led_scales.size()) +
                                                 " scales and " + std::to_string(frames.size()) + " frames");
  for (std::size_t k = 0; k < frames.size(); ++k) {
    if (frames[k].empty() || frames[k].size() != frames[0].size() || frames[k].channels() != 1)
      return Ended(Termination::kInvalidInput,
                   "frame " + std::to_string(k) + " is not single-channel or differs from frame 0 in size");
    if (!(led_scales[k] > 0.0)) return Ended(Termination::kInvalidInput, "LED " + std::to_string(k) + " has a non-positive scale");
  }
  if (points_mm.type() != CV_32FC3 || points_mm.size() != frames[0].size() || !cv::checkRange(points_mm))
    return Ended(Termination::kInvalidInput, "points_mm must be finite CV_32FC3 points, one per frame pixel");
  cv::Mat source;
  latlong.convertTo(source, CV_MAKETYPE(CV_32F, latlong.channels()));
  cv::resize(source, source, cv::Size(options.map_width_px, options.map_width_px / 2), 0.0, 0.0, cv::INTER_AREA);
  const UpperTexels texels(source);
  const int channels = texels.channels, lights = static_cast<int>(leds.size());
  std::vector<camera::PreparedNearLight> prepared;
  for (const camera::NearLight& led : leds) prepared.emplace_back(led);
  const std::vector<int> grid_rows = GridPositions(points_mm.rows, options.grid_px),
                         grid_cols = GridPositions(points_mm.cols, options.grid_px);
  timer.SetupDone(&summary);

  // Each grid point's weights: [(grid row * grid columns + grid column) * lights + k] * channels + channel.
  const std::size_t grid_points = grid_rows.size() * grid_cols.size(), per_point = static_cast<std::size_t>(lights) * channels;
  std::vector<double> node_weights(grid_points * per_point, 0.0);
#pragma omp parallel for schedule(dynamic, 1)
  for (std::size_t g = 0; g < grid_points; ++g) {
    const cv::Vec3f& p = points_mm.at<cv::Vec3f>(grid_rows[g / grid_cols.size()], grid_cols[g % grid_cols.size()]);
    std::vector<Eigen::Vector3d> directions(lights);
    std::vector<double> irradiance(lights);
    std::vector<char> reaches(lights);
    for (int k = 0; k < lights; ++k) {
      irradiance[k] = led_scales[k] * prepared[k].RelativeIrradiance(Eigen::Vector3d(p[0], p[1], p[2]), &directions[k]);
      reaches[k] = irradiance[k] > 0.0;
    }
    const Eigen::MatrixXd radiance = NearestLedRadiance(texels, directions, reaches);
    for (int k = 0; k < lights; ++k)
      for (int ch = 0; ch < channels; ++ch)
        node_weights[g * per_point + k * channels + ch] = reaches[k] ? radiance(k, ch) / irradiance[k] : 0.0;
  }

  std::vector<int> row_cell, col_cell;
  std::vector<float> row_fraction, col_fraction;
  GridCells(grid_rows, points_mm.rows, &row_cell, &row_fraction);
  GridCells(grid_cols, points_mm.cols, &col_cell, &col_fraction);
  std::vector<cv::Mat> converted(frames.size());
  for (std::size_t k = 0; k < frames.size(); ++k) frames[k].convertTo(converted[k], CV_32F);
  cv::Mat relit(points_mm.size(), CV_32FC(channels));
  const std::size_t last_col = grid_cols.size() - 1, last_row = grid_rows.size() - 1;
#pragma omp parallel for schedule(static)
  for (int r = 0; r < relit.rows; ++r) {
    const std::size_t r0 = row_cell[r], r1 = std::min(r0 + 1, last_row);
    const double fr = row_fraction[r];
    float* out = relit.ptr<float>(r);
    for (int c = 0; c < relit.cols; ++c) {
      const std::size_t c0 = col_cell[c], c1 = std::min(c0 + 1, last_col);
      const double fc = col_fraction[c];
      const double* w00 = &node_weights[(r0 * grid_cols.size() + c0) * per_point];
      const double* w01 = &node_weights[(r0 * grid_cols.size() + c1) * per_point];
      const double* w10 = &node_weights[(r1 * grid_cols.size() + c0) * per_point];
      const double* w11 = &node_weights[(r1 * grid_cols.size() + c1) * per_point];
      double sum[3] = {0.0, 0.0, 0.0};
      for (int k = 0; k < lights; ++k) {
        const double value = converted[k].at<float>(r, c);
        for (int ch = 0; ch < channels; ++ch) {
          const int i = k * channels + ch;
          const double w = (1.0 - fr) * ((1.0 - fc) * w00[i] + fc * w01[i]) + fr * ((1.0 - fc) * w10[i] + fc * w11[i]);
          sum[ch] += w * value;
        }
      }
      // Columns are R, G, B; the image stores B, G, R.
      for (int ch = 0; ch < channels; ++ch) out[c * channels + ch] = static_cast<float>(sum[channels == 3 ? 2 - ch : 0]);
    }
  }
  *image = relit;
  timer.Finish(&summary);
  summary.termination = Termination::kSuccess;
  return summary;
}

}  // namespace photorig::solvers::lighting
