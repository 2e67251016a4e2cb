#include "photorig/sim/scene.h"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace photorig::sim {

double AlbedoTexture::At(double x_mm, double y_mm) const {
  switch (pattern) {
    case Pattern::kUniform: return high;
    case Pattern::kChecker: {
      const long cx = static_cast<long>(std::floor(x_mm / period_mm));
      const long cy = static_cast<long>(std::floor(y_mm / period_mm));
      return ((cx + cy) & 1) ? low : high;
    }
    case Pattern::kRings: {
      // Smooth rings: albedo varies continuously, as a painted object would.
      const double r = std::hypot(x_mm, y_mm);
      return low + (high - low) * 0.5 * (1.0 + std::cos(2.0 * M_PI * r / period_mm));
    }
  }
  return high;
}

Scene::Shape Scene::ParseShape(const std::string& name) {
  if (name == "sphere") return Shape::kSphere;
  if (name == "bumps") return Shape::kBumps;
  throw std::invalid_argument("unknown shape '" + name + "' (expected sphere or bumps)");
}

const char* Scene::ShapeName(Shape shape) { return shape == Shape::kSphere ? "sphere" : "bumps"; }

std::vector<Bump> Scene::DefaultBumps(double frame_width_mm) {
  // A 3 x 3 grid alternating bumps and dimples, steep enough to cast shadows
  // under lights below about 45 degrees elevation.
  std::vector<Bump> bumps;
  const double spacing = frame_width_mm / 3.0;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      Bump bump;
      bump.x_mm = (i - 1) * spacing;
      bump.y_mm = (j - 1) * spacing;
      bump.sigma_mm = spacing * (0.14 + 0.03 * ((i + 2 * j) % 3));
      bump.amplitude_mm = ((i + j) % 2 == 0 ? 1.0 : -0.7) * 1.6 * bump.sigma_mm;
      bumps.push_back(bump);
    }
  }
  return bumps;
}

SurfaceMaps SampleSurface(const Scene& scene, int width, int height, double pixel_pitch_mm) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  SurfaceMaps maps;
  maps.pixel_pitch_mm = pixel_pitch_mm;
  maps.normals.create(height, width, CV_32FC3);
  maps.normals.setTo(cv::Scalar::all(nan));
  maps.albedo.create(height, width, CV_32F);
  maps.albedo.setTo(nan);
  maps.height.create(height, width, CV_32F);
  maps.height.setTo(nan);
  maps.mask = cv::Mat::zeros(height, width, CV_8U);

  for (int r = 0; r < height; ++r) {
    const double y = (0.5 * height - r - 0.5) * pixel_pitch_mm;
    for (int c = 0; c < width; ++c) {
      const double x = (c + 0.5 - 0.5 * width) * pixel_pitch_mm;
      double nx, ny, nz, z;
      if (scene.shape == Scene::Shape::kSphere) {
        const double rr = scene.sphere_radius_mm;
        const double d2 = x * x + y * y;
        if (d2 >= rr * rr) continue;
        z = std::sqrt(rr * rr - d2);
        nx = x / rr;
        ny = y / rr;
        nz = z / rr;
      } else {
        // z = sum a exp(-d^2 / 2 s^2); the normal is (-dz/dx, -dz/dy, 1) normalised.
        double dzdx = 0.0, dzdy = 0.0;
        z = 0.0;
        for (const Bump& b : scene.bumps) {
          const double dx = x - b.x_mm, dy = y - b.y_mm;
          const double s2 = b.sigma_mm * b.sigma_mm;
          const double g = b.amplitude_mm * std::exp(-(dx * dx + dy * dy) / (2.0 * s2));
          z += g;
          dzdx -= g * dx / s2;
          dzdy -= g * dy / s2;
        }
        const double length = std::sqrt(dzdx * dzdx + dzdy * dzdy + 1.0);
        nx = -dzdx / length;
        ny = -dzdy / length;
        nz = 1.0 / length;
      }
      maps.normals.at<cv::Vec3f>(r, c) = cv::Vec3f(float(nx), float(ny), float(nz));
      maps.albedo.at<float>(r, c) = static_cast<float>(scene.albedo.At(x, y));
      maps.height.at<float>(r, c) = static_cast<float>(z);
      maps.mask.at<std::uint8_t>(r, c) = 255;
    }
  }
  return maps;
}

}  // namespace photorig::sim
