#include "photorig/sim/renderer.h"

#include <algorithm>
#include <cmath>

namespace photorig::sim {

cv::Mat CastShadowMask(const SurfaceMaps& surface, const Eigen::Vector3d& direction) {
  const cv::Mat& height = surface.height;
  cv::Mat shadow = cv::Mat::zeros(height.size(), CV_8U);
  if (direction.z() <= 0.0) return shadow;  // below the horizon: everything is in attached shadow anyway
  double max_height = 0.0;
  cv::minMaxLoc(height, nullptr, &max_height, nullptr, nullptr, surface.mask);
  const double horizontal = std::hypot(direction.x(), direction.y());
  if (horizontal < 1e-9) return shadow;  // light straight above: nothing shadows
  // One step = half a pixel along the light's footprint; the ray climbs
  // rise_per_step millimetres each step.
  const double step_px = 0.5;
  const double dc = step_px * direction.x() / horizontal;
  const double dr = -step_px * direction.y() / horizontal;  // rows grow downwards
  const double rise_per_step = step_px * surface.pixel_pitch_mm * direction.z() / horizontal;
  const int rows = height.rows, cols = height.cols;

#pragma omp parallel for schedule(dynamic, 8)
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const float h0 = height.at<float>(r, c);
      if (!std::isfinite(h0)) continue;
      double cc = c, rr = r, ray = h0;
      while (ray < max_height) {
        cc += dc;
        rr += dr;
        ray += rise_per_step;
        const int ic = static_cast<int>(std::lround(cc)), ir = static_cast<int>(std::lround(rr));
        if (ic < 0 || ir < 0 || ic >= cols || ir >= rows) break;
        const float h = height.at<float>(ir, ic);
        if (std::isfinite(h) && h > ray) {
          shadow.at<std::uint8_t>(r, c) = 1;
          break;
        }
      }
    }
  }
  return shadow;
}

cv::Mat RenderRadiance(const SurfaceMaps& surface, bool cast_shadows,
                       const std::vector<DirectionalLight>& lights, const std::vector<double>& levels) {
  cv::Mat radiance = cv::Mat::zeros(surface.normals.size(), CV_32F);
  for (std::size_t k = 0; k < lights.size(); ++k) {
    const double level = k < levels.size() ? levels[k] : 0.0;
    if (level <= 0.0) continue;
    const Eigen::Vector3d w = lights[k].direction;
    const float scale = static_cast<float>(level * lights[k].irradiance / M_PI);
    const cv::Mat shadow = cast_shadows ? CastShadowMask(surface, w) : cv::Mat();
    const float wx = float(w.x()), wy = float(w.y()), wz = float(w.z());
#pragma omp parallel for schedule(static)
    for (int r = 0; r < radiance.rows; ++r) {
      const auto* n = surface.normals.ptr<cv::Vec3f>(r);
      const float* albedo = surface.albedo.ptr<float>(r);
      const std::uint8_t* blocked = shadow.empty() ? nullptr : shadow.ptr<std::uint8_t>(r);
      float* out = radiance.ptr<float>(r);
      for (int c = 0; c < radiance.cols; ++c) {
        if (!std::isfinite(albedo[c]) || (blocked && blocked[c])) continue;
        const float cosine = n[c][0] * wx + n[c][1] * wy + n[c][2] * wz;
        if (cosine > 0.0f) out[c] += scale * albedo[c] * cosine;
      }
    }
  }
  return radiance;
}

}  // namespace photorig::sim
