#include "photorig/sim/renderer.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>

namespace photorig::sim {
namespace {

using Eigen::Vector3d;

// Height of the heightfield at continuous pixel coordinates (col, row),
// interpolated between the two rows (or columns) either side; NaN where the
// surface is absent.
float Interpolate(const cv::Mat& height, double col, double row, bool along_rows) {
  const double f = along_rows ? row : col;
  const int i0 = static_cast<int>(std::floor(f));
  const double t = f - i0;
  auto at = [&](int i) {
    const int r = along_rows ? i : static_cast<int>(row), c = along_rows ? static_cast<int>(col) : i;
    if (r < 0 || c < 0 || r >= height.rows || c >= height.cols) return std::numeric_limits<float>::quiet_NaN();
    return height.at<float>(r, c);
  };
  const float a = at(i0), b = at(i0 + 1);
  if (!std::isfinite(a)) return t > 0.5 ? b : a;
  if (!std::isfinite(b)) return t < 0.5 ? a : b;
  return static_cast<float>(a + t * (b - a));
}

}  // namespace

double Light::IrradianceAt(const Vector3d& point_mm, Vector3d* towards_light) const {
  if (!position_mm) {
    *towards_light = direction;
    return irradiance;
  }
  const Vector3d to = *position_mm - point_mm;
  const double d2 = to.squaredNorm();
  *towards_light = to / std::sqrt(d2);
  const double cos_axis = -axis.dot(*towards_light);
  if (cos_axis <= 0.0) return 0.0;
  // Intensity on the axis chosen so that the irradiance at the origin is `irradiance`.
  const double origin_d2 = position_mm->squaredNorm();
  const double origin_cos = std::max(1e-12, axis.dot(-*position_mm) / std::sqrt(origin_d2));
  const double intensity = irradiance * origin_d2 / std::pow(origin_cos, cos_exponent);
  return intensity * std::pow(cos_axis, cos_exponent) / d2;
}

double Light::AngularRadiusAt(const Vector3d& point_mm) const {
  if (!position_mm) return angular_radius_rad;
  return std::asin(std::min(1.0, emitter_radius_mm / (*position_mm - point_mm).norm()));
}

cv::Mat CastShadowMask(const SurfaceMaps& surface, const Vector3d& direction) {
  const cv::Mat& height = surface.height;
  cv::Mat shadow = cv::Mat::zeros(height.size(), CV_8U);
  const double horizontal = std::hypot(direction.x(), direction.y());
  // Below the horizon everything is in attached shadow anyway; straight above nothing is cast.
  if (direction.z() <= 0.0 || horizontal < 1e-9) return shadow;
  const int rows = height.rows, cols = height.cols;
  // Towards the light in pixel coordinates (rows grow downwards).
  const double ux = direction.x() / horizontal, uy = -direction.y() / horizontal;
  // Lines advance one pixel per step along the dominant axis and `slope`
  // pixels along the other; a line's cross coordinate at step k is
  // start + k * slope, so the lines (one per integer start) visit each pixel once.
  const bool along_cols = std::abs(ux) >= std::abs(uy);
  const int length = along_cols ? cols : rows, breadth = along_cols ? rows : cols;
  const double main = along_cols ? ux : uy, cross = along_cols ? uy : ux;
  const int first = main > 0 ? length - 1 : 0, step = main > 0 ? -1 : 1;  // start on the light's side
  const double slope = -cross / std::abs(main);
  const double step_mm = surface.pixel_pitch_mm * std::sqrt(1.0 + slope * slope);
  const double drop = step_mm * direction.z() / horizontal;  // the shadow line falls this much per step
  const double span = slope * (length - 1);
  const int start_min = static_cast<int>(std::floor(std::min(0.0, -span))) - 1;
  const int start_max = static_cast<int>(std::ceil(std::max(0.0, -span))) + breadth;

#pragma omp parallel for schedule(dynamic, 16)
  for (int start = start_min; start <= start_max; ++start) {
    double horizon = -std::numeric_limits<double>::infinity();
    for (int k = 0; k < length; ++k) {
      const int m = first + step * k;
      const double x = start + k * slope;  // exact cross coordinate
      const int owner = start + static_cast<int>(std::floor(k * slope + 0.5));
      const double col = along_cols ? m : x, row = along_cols ? x : m;
      const float h = Interpolate(height, col, row, along_cols);
      horizon -= drop;
      if (!std::isfinite(h)) continue;
      if (h < horizon - 1e-6 && owner >= 0 && owner < breadth) {
        const int r = along_cols ? owner : m, c = along_cols ? m : owner;
        if (std::isfinite(height.at<float>(r, c))) shadow.at<std::uint8_t>(r, c) = 1;
      }
      horizon = std::max(horizon, double(h));
    }
  }
  return shadow;
}

cv::Mat CastShadowMask(const SurfaceMaps& surface, const Light& light) {
  if (!light.position_mm) return CastShadowMask(surface, light.direction);
  const cv::Mat& height = surface.height;
  cv::Mat shadow = cv::Mat::zeros(height.size(), CV_8U);
  double max_height = 0.0;
  cv::minMaxLoc(height, nullptr, &max_height, nullptr, nullptr, surface.mask);
  const int rows = height.rows, cols = height.cols;
  const double pitch = surface.pixel_pitch_mm;
#pragma omp parallel for schedule(dynamic, 8)
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const float h0 = height.at<float>(r, c);
      if (!std::isfinite(h0)) continue;
      const Vector3d p((c + 0.5 - 0.5 * cols) * pitch, (0.5 * rows - r - 0.5) * pitch, h0);
      const Vector3d to = *light.position_mm - p;
      const double horizontal = std::hypot(to.x(), to.y());
      if (to.z() <= 0.0 || horizontal < 1e-9) continue;
      // Half-pixel steps along the LED's footprint until the ray clears the
      // highest point or reaches the LED.
      const double steps_to_led = horizontal / (0.5 * pitch);
      const double dc = 0.5 * to.x() / horizontal, dr = -0.5 * to.y() / horizontal;
      const double rise = to.z() / steps_to_led;
      double ray = h0;
      for (int s = 1; s < steps_to_led && ray < max_height; ++s) {
        ray += rise;
        const int ic = static_cast<int>(std::lround(c + s * dc)), ir = static_cast<int>(std::lround(r + s * dr));
        if (ic < 0 || ir < 0 || ic >= cols || ir >= rows) break;
        const float h = height.at<float>(ir, ic);
        if (std::isfinite(h) && h > ray) {
          shadow.at<std::uint8_t>(r, c) = 1;
          break;
        }
      }
    }
  return shadow;
}

namespace {

// The fraction of pixel (r, c) whose mirror direction falls inside a near
// LED's disc. Its image on a mirror ball spans a pixel or less, so a sample
// at the pixel's centre would find it or miss it whole; a camera integrates
// over the pixel. 4 x 4 sub-samples, the surface carried across the pixel by
// its central differences (one-sided at the object's edge).
double NearHighlightCoverage(const SurfaceMaps& surface, int r, int c, const Light& light) {
  const auto at = [&surface](const cv::Mat& map, int row, int col) {
    const cv::Vec3f& v = map.at<cv::Vec3f>(row, col);
    return Vector3d(v[0], v[1], v[2]);
  };
  const auto on = [&surface](int row, int col) {
    return row >= 0 && col >= 0 && row < surface.mask.rows && col < surface.mask.cols && surface.mask.at<std::uint8_t>(row, col);
  };
  // d/dcol and d/drow of a map at the pixel.
  const auto slope = [&](const cv::Mat& map, int dr, int dc) -> Vector3d {
    const bool plus = on(r + dr, c + dc), minus = on(r - dr, c - dc);
    if (plus && minus) return 0.5 * (at(map, r + dr, c + dc) - at(map, r - dr, c - dc));
    if (plus) return at(map, r + dr, c + dc) - at(map, r, c);
    if (minus) return at(map, r, c) - at(map, r - dr, c - dc);
    return Vector3d::Zero();
  };
  const Vector3d n0 = at(surface.normals, r, c), p0 = at(surface.position, r, c), w0 = at(surface.view, r, c);
  const Vector3d dn_c = slope(surface.normals, 0, 1), dn_r = slope(surface.normals, 1, 0);
  const Vector3d dp_c = slope(surface.position, 0, 1), dp_r = slope(surface.position, 1, 0);
  const Vector3d dw_c = slope(surface.view, 0, 1), dw_r = slope(surface.view, 1, 0);
  // Far from the disc (by more than the mirror direction turns across the pixel): none of it.
  const double alpha = light.AngularRadiusAt(p0);
  const Vector3d to_light0 = (*light.position_mm - p0).normalized();
  const double turn = 2.0 * (dn_c.norm() + dn_r.norm()) + dw_c.norm() + dw_r.norm();
  if (std::acos(std::clamp(MirrorDirection(n0, w0).dot(to_light0), -1.0, 1.0)) > alpha + turn) return 0.0;
  constexpr int kSub = 4;
  int inside = 0;
  for (int i = 0; i < kSub; ++i)
    for (int j = 0; j < kSub; ++j) {
      const double dr = (i + 0.5) / kSub - 0.5, dc = (j + 0.5) / kSub - 0.5;
      const Vector3d n = (n0 + dc * dn_c + dr * dn_r).normalized();
      const Vector3d wo = (w0 + dc * dw_c + dr * dw_r).normalized();
      const Vector3d p = p0 + dc * dp_c + dr * dp_r;
      const Vector3d to_light = (*light.position_mm - p).normalized();
      if (MirrorDirection(n, wo).dot(to_light) >= std::cos(light.AngularRadiusAt(p))) ++inside;
    }
  return static_cast<double>(inside) / (kSub * kSub);
}

}  // namespace

cv::Mat RenderRadiance(const SurfaceMaps& surface, const Brdf& brdf, bool cast_shadows,
                       const std::vector<Light>& lights, const std::vector<double>& levels) {
  cv::Mat radiance = cv::Mat::zeros(surface.normals.size(), CV_32F);
  const bool delta = brdf.IsDelta();
  for (std::size_t k = 0; k < lights.size(); ++k) {
    const double level = k < levels.size() ? levels[k] : 0.0;
    if (level <= 0.0) continue;
    const Light& light = lights[k];
    const cv::Mat shadow = cast_shadows ? CastShadowMask(surface, light) : cv::Mat();
#pragma omp parallel for schedule(static)
    for (int r = 0; r < radiance.rows; ++r) {
      const auto* normal = surface.normals.ptr<cv::Vec3f>(r);
      const auto* view = surface.view.ptr<cv::Vec3f>(r);
      const auto* position = surface.position.ptr<cv::Vec3f>(r);
      const auto* params = surface.brdf_params.ptr<cv::Vec4f>(r);
      const std::uint8_t* mask = surface.mask.ptr<std::uint8_t>(r);
      const std::uint8_t* blocked = shadow.empty() ? nullptr : shadow.ptr<std::uint8_t>(r);
      float* out = radiance.ptr<float>(r);
      for (int c = 0; c < radiance.cols; ++c) {
        if (!mask[c] || (blocked && blocked[c])) continue;
        const Vector3d n(normal[c][0], normal[c][1], normal[c][2]);
        const Vector3d p(position[c][0], position[c][1], position[c][2]);
        const Vector3d wo(view[c][0], view[c][1], view[c][2]);
        const BrdfParams bp{params[c][0], params[c][1], params[c][2], params[c][3]};
        Vector3d wi;
        const double e = light.IrradianceAt(p, &wi);
        const double cosine = n.dot(wi);
        if (e <= 0.0 || cosine <= 0.0) continue;
        if (delta) {
          const double alpha = light.AngularRadiusAt(p);
          // A distant light's disc is sampled at the pixel's centre, a near LED's integrated over the pixel.
          const double coverage = light.position_mm ? NearHighlightCoverage(surface, r, c, light)
                                                    : (MirrorDirection(n, wo).dot(wi) < std::cos(alpha) ? 0.0 : 1.0);
          if (coverage == 0.0) continue;
          const double s = std::sin(alpha);
          out[c] += static_cast<float>(coverage * level * brdf.DeltaReflectance(bp) * e / (M_PI * s * s));
        } else {
          out[c] += static_cast<float>(level * brdf.Eval(n, wi, wo, bp) * e * cosine);
        }
      }
    }
  }
  return radiance;
}

cv::Mat RenderRadiance(const SurfaceMaps& surface, bool cast_shadows, const std::vector<Light>& lights,
                       const std::vector<double>& levels) {
  return RenderRadiance(surface, *MakeBrdf(Brdf::Model::kLambertian), cast_shadows, lights, levels);
}

namespace {

std::uint64_t SplitMix64(std::uint64_t* state) {
  std::uint64_t z = (*state += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

double Uniform(std::uint64_t* state) { return (SplitMix64(state) >> 11) * 0x1.0p-53; }

// The k-th of strata x strata stratified cosine-weighted directions about n
// (t, b: tangents completing the frame): a uniform point in the cell of the
// unit square, mapped to the disc and lifted to the hemisphere.
Vector3d CosineWeighted(const Vector3d& n, const Vector3d& t, const Vector3d& b, int k, int strata,
                        std::uint64_t* state) {
  const double u1 = (k / strata + Uniform(state)) / strata, u2 = (k % strata + Uniform(state)) / strata;
  const double radius = std::sqrt(u1), phi = 2.0 * M_PI * u2;
  return radius * std::cos(phi) * t + radius * std::sin(phi) * b + std::sqrt(std::max(0.0, 1.0 - u1)) * n;
}

// Bilinear height at continuous pixel-centre coordinates (col, row), so that
// a plane is exactly a plane to the march; NaN where any of the four samples
// is off the surface (a step there would make edges cast false hits).
float HeightAt(const cv::Mat& height, double col, double row) {
  const int c0 = static_cast<int>(std::floor(col)), r0 = static_cast<int>(std::floor(row));
  if (c0 < 0 || r0 < 0 || c0 + 1 >= height.cols || r0 + 1 >= height.rows) return std::numeric_limits<float>::quiet_NaN();
  const double tc = col - c0, tr = row - r0;
  const float* upper = height.ptr<float>(r0) + c0;
  const float* lower = height.ptr<float>(r0 + 1) + c0;
  return static_cast<float>((1 - tr) * ((1 - tc) * upper[0] + tc * upper[1]) + tr * ((1 - tc) * lower[0] + tc * lower[1]));
}

// Highest surface point per block of kBlock x kBlock pixels (with a one-pixel
// apron, as the bilinear lookup reads the next row and column): a ray above a
// block's maximum crosses the whole block in one jump.
constexpr int kBlock = 16;

cv::Mat BlockMaxima(const cv::Mat& height) {
  const int block_rows = (height.rows + kBlock - 1) / kBlock, block_cols = (height.cols + kBlock - 1) / kBlock;
  cv::Mat maxima(block_rows, block_cols, CV_32F, cv::Scalar(-std::numeric_limits<float>::infinity()));
  for (int r = 0; r < height.rows; ++r)
    for (int c = 0; c < height.cols; ++c) {
      const float h = height.at<float>(r, c);
      if (!std::isfinite(h)) continue;
      // Every block whose lookups may read this sample.
      for (int br = std::max(0, (r - 1) / kBlock); br <= r / kBlock; ++br)
        for (int bc = std::max(0, (c - 1) / kBlock); bc <= c / kBlock; ++bc)
          maxima.at<float>(br, bc) = std::max(maxima.at<float>(br, bc), h);
    }
  return maxima;
}

// Steps of (dc, dr) from (col, row) until the point leaves the block it is in.
int StepsToLeaveBlock(double col, double row, double dc, double dr) {
  auto axis_steps = [](double x, double dx) {
    if (std::abs(dx) < 1e-12) return std::numeric_limits<double>::infinity();
    const double start = std::floor(x / kBlock) * kBlock;
    return dx > 0 ? (start + kBlock - x) / dx : (x - start) / -dx;
  };
  return static_cast<int>(std::min(axis_steps(col, dc), axis_steps(row, dr))) + 1;
}

}  // namespace

cv::Mat RenderOneBounce(const SurfaceMaps& surface, const Brdf& brdf, const cv::Mat& direct, int samples,
                        std::uint64_t seed) {
  cv::Mat bounce = cv::Mat::zeros(direct.size(), CV_32F);
  if (samples <= 0 || brdf.IsDelta() || !surface.height_on_pixel_grid) return bounce;
  const cv::Mat& height = surface.height;
  double max_height = 0.0;
  cv::minMaxLoc(height, nullptr, &max_height, nullptr, nullptr, surface.mask);
  const int rows = height.rows, cols = height.cols;
  const double pitch = surface.pixel_pitch_mm;
  const cv::Mat block_max = BlockMaxima(height);
  // Stratified over a grid of strata x strata cells of the unit square.
  const int strata = std::max(1, static_cast<int>(std::lround(std::sqrt(samples))));
  const int count = strata * strata;
#pragma omp parallel for schedule(dynamic, 4)
  for (int r = 0; r < rows; ++r) {
    const auto* normal = surface.normals.ptr<cv::Vec3f>(r);
    const auto* view = surface.view.ptr<cv::Vec3f>(r);
    const auto* params = surface.brdf_params.ptr<cv::Vec4f>(r);
    const std::uint8_t* mask = surface.mask.ptr<std::uint8_t>(r);
    float* out = bounce.ptr<float>(r);
    for (int c = 0; c < cols; ++c) {
      const float h0 = height.at<float>(r, c);
      if (!mask[c] || !std::isfinite(h0)) continue;
      const Vector3d n(normal[c][0], normal[c][1], normal[c][2]);
      const Vector3d wo(view[c][0], view[c][1], view[c][2]);
      const BrdfParams bp{params[c][0], params[c][1], params[c][2], params[c][3]};
      const Vector3d t = n.unitOrthogonal(), b = n.cross(t);
      std::uint64_t state = seed ^ (static_cast<std::uint64_t>(r) * cols + c) * 0x2545f4914f6cdd1dULL;
      double sum = 0.0;
      for (int k = 0; k < count; ++k) {
        const Vector3d wi = CosineWeighted(n, t, b, k, strata, &state);
        const double horizontal = std::hypot(wi.x(), wi.y());
        if (horizontal < 1e-9) continue;  // straight up leaves a heightfield
        // Half-pixel steps; the ray's height changes by `rise` per step.
        const double dc = 0.5 * wi.x() / horizontal, dr = -0.5 * wi.y() / horizontal;
        const double rise = 0.5 * pitch * wi.z() / horizontal;
        double ray = h0;
        for (int s = 1;; ++s) {
          ray += rise;
          if (rise >= 0.0 && ray > max_height) break;
          const double col = c + s * dc, row = r + s * dr;
          if (col < -0.5 || row < -0.5 || col > cols - 0.5 || row > rows - 0.5) break;
          if (col >= 0.0 && row >= 0.0) {
            // Above everything in this block all the way to its exit: jump there.
            const int jump = StepsToLeaveBlock(col, row, dc, dr) - 1;
            const float top = block_max.at<float>(static_cast<int>(row) / kBlock, static_cast<int>(col) / kBlock);
            if (jump > 0 && std::min(ray, ray + jump * rise) > top) {
              s += jump - 1;
              ray += (jump - 1) * rise;
              continue;
            }
          }
          const float h = HeightAt(height, col, row);
          if (!std::isfinite(h) || h <= ray) continue;
          const int qc = static_cast<int>(std::lround(col)), qr = static_cast<int>(std::lround(row));
          if (qc == c && qr == r) continue;  // still on the starting pixel
          if (qc >= 0 && qr >= 0 && qc < cols && qr < rows)
            sum += brdf.Eval(n, wi, wo, bp) * direct.at<float>(qr, qc);
          break;
        }
      }
      out[c] = static_cast<float>(M_PI * sum / count);
    }
  }
  return bounce;
}

bool AmbientLight::IsValid(std::string* why) const {
  if (!(dome_fraction >= 0.0 && dome_fraction <= 1.0)) {
    *why = "the dome's share of an LED's light must lie in [0, 1]";
    return false;
  }
  if (!(stray_irradiance >= 0.0)) {
    *why = "stray irradiance must be >= 0";
    return false;
  }
  if (samples < 1 || samples > 65536) {
    *why = "ambient samples must lie in [1, 65536]";
    return false;
  }
  return true;
}

cv::Mat RenderSkyResponse(const SurfaceMaps& surface, const Brdf& brdf, int samples, std::uint64_t seed) {
  cv::Mat response = cv::Mat::zeros(surface.mask.size(), CV_32F);
  const int strata = std::max(1, static_cast<int>(std::lround(std::sqrt(samples))));
  const int count = strata * strata;
#pragma omp parallel for schedule(dynamic, 4)
  for (int r = 0; r < response.rows; ++r) {
    const auto* normal = surface.normals.ptr<cv::Vec3f>(r);
    const auto* view = surface.view.ptr<cv::Vec3f>(r);
    const auto* params = surface.brdf_params.ptr<cv::Vec4f>(r);
    const std::uint8_t* mask = surface.mask.ptr<std::uint8_t>(r);
    float* out = response.ptr<float>(r);
    for (int c = 0; c < response.cols; ++c) {
      if (!mask[c]) continue;
      const Vector3d n(normal[c][0], normal[c][1], normal[c][2]);
      const Vector3d wo(view[c][0], view[c][1], view[c][2]);
      const BrdfParams bp{params[c][0], params[c][1], params[c][2], params[c][3]};
      if (brdf.IsDelta()) {  // the sky's radiance 1 / pi seen along the mirror direction
        out[c] = MirrorDirection(n, wo).z() > 0.0 ? static_cast<float>(brdf.DeltaReflectance(bp) / M_PI) : 0.0f;
        continue;
      }
      const Vector3d t = n.unitOrthogonal(), b = n.cross(t);
      std::uint64_t state = seed ^ (static_cast<std::uint64_t>(r) * response.cols + c) * 0x9fb21c651e98df25ULL;
      double sum = 0.0;
      for (int k = 0; k < count; ++k) {
        const Vector3d wi = CosineWeighted(n, t, b, k, strata, &state);
        if (wi.z() > 0.0) sum += brdf.Eval(n, wi, wo, bp);
      }
      out[c] = static_cast<float>(sum / count);
    }
  }
  return response;
}

cv::Mat RenderTransmission(const cv::Mat& line_integrals, double backlight_radiance) {
  cv::Mat radiance;
  cv::exp(-line_integrals, radiance);
  return radiance * backlight_radiance;
}

}  // namespace photorig::sim
