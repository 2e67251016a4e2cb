#pragma once
// Simulated scenes with known spatially varying reflectance for the
// reflectance solver's tests, benchmark and chart: a sphere (every normal of
// the visible hemisphere, so every material meets the dome's highlights) cut
// into vertical bands of materials, each with a checkered albedo of its own
// colour, lit by a dome of rings of LEDs and seen orthographically from +z.
// Rendered with the brdf module's models through RenderReflectance, with
// Gaussian read noise and shot noise.

#include "photorig/solvers/reflectance/fit.h"
#include "photorig/solvers/reflectance/relighting.h"

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace photorig::testing {

namespace refl = photorig::solvers::reflectance;
namespace brdf = photorig::solvers::brdf;

struct SvbrdfScene {
  refl::ReflectanceStack stack;
  refl::ReflectanceMaps truth;  // albedo, material map, normals, materials
  cv::Mat mask;
  std::vector<cv::Mat> clean;   // noise-free images
};

struct SceneSpec {
  int size = 48;                               // pixels per side
  int channels = 3;
  std::vector<refl::MaterialFit> materials;    // bands from left to right
  std::vector<Eigen::Vector3d> band_colour;    // per material, albedo chromaticity scale
  std::vector<Eigen::Vector3d> lights;         // empty: DomeLights()
  double read_sigma = 0.002;                   // image units (peak diffuse ~0.5)
  double shot_fraction = 0.005;                // relative deviation of the signal
  unsigned seed = 7;
};

// Rings at elevations 15..75 degrees plus one at the zenith.
inline std::vector<Eigen::Vector3d> DomeLights(int rings = 4, int per_ring = 10, double lowest_deg = 15.0,
                                               double highest_deg = 75.0) {
  std::vector<Eigen::Vector3d> lights{Eigen::Vector3d(0.0, 0.0, 1.0)};
  for (int r = 0; r < rings; ++r) {
    const double el = (lowest_deg + (highest_deg - lowest_deg) * r / std::max(1, rings - 1)) * M_PI / 180.0;
    for (int a = 0; a < per_ring; ++a) {
      const double az = (a + 0.5 * r) * 2.0 * M_PI / per_ring;
      lights.emplace_back(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
    }
  }
  return lights;
}

inline refl::MaterialFit Matte() { return {}; }
inline refl::MaterialFit Phong(double k_s, double exponent) {
  refl::MaterialFit m;
  m.model = brdf::Model::kBlinnPhong;
  m.specular = Eigen::Vector3d::Constant(k_s);
  m.shape = exponent;
  return m;
}
inline refl::MaterialFit Ggx(double f0, double roughness) {
  refl::MaterialFit m;
  m.model = brdf::Model::kGgx;
  m.specular = Eigen::Vector3d::Constant(f0);
  m.shape = roughness;
  return m;
}

inline SvbrdfScene MakeScene(const SceneSpec& spec) {
  SvbrdfScene scene;
  const int n = spec.size, C = spec.channels;
  const double radius = 0.47 * n, centre = 0.5 * (n - 1);
  const int bands = static_cast<int>(spec.materials.size());
  refl::ReflectanceMaps& t = scene.truth;
  t.materials = spec.materials;
  t.normals = cv::Mat(n, n, CV_32FC3, cv::Scalar::all(std::numeric_limits<float>::quiet_NaN()));
  t.albedo = cv::Mat(n, n, CV_32FC(C), cv::Scalar::all(std::numeric_limits<float>::quiet_NaN()));
  t.material = cv::Mat(n, n, CV_8U, cv::Scalar(255));
  t.flags = cv::Mat(n, n, CV_8U, cv::Scalar(static_cast<int>(refl::PixelFlag::kOutsideMask)));
  scene.mask = cv::Mat(n, n, CV_8U, cv::Scalar(0));
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) {
      const double x = (c - centre) / radius, y = (centre - r) / radius, rr = x * x + y * y;
      if (rr >= 0.97) continue;
      const double z = std::sqrt(1.0 - rr);
      t.normals.at<cv::Vec3f>(r, c) = cv::Vec3f(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
      const int m = std::min(bands - 1, static_cast<int>((x + 1.0) * 0.5 * bands));
      t.material.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(m);
      t.flags.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(refl::PixelFlag::kFitted);
      scene.mask.at<std::uint8_t>(r, c) = 255;
      // A checker of two albedos (0.3 and 0.7 times the band's colour), 6 pixels a square.
      const bool bright = ((r / 6) + (c / 6)) % 2 == 0;
      const Eigen::Vector3d colour = m < static_cast<int>(spec.band_colour.size()) ? spec.band_colour[m] : Eigen::Vector3d::Ones();
      float* a = t.albedo.ptr<float>(r) + c * C;
      for (int ch = 0; ch < C; ++ch) a[ch] = static_cast<float>((bright ? 0.7 : 0.3) * colour[ch]);
    }
  scene.stack.light_directions = spec.lights.empty() ? DomeLights() : spec.lights;
  for (auto& l : scene.stack.light_directions) l.normalize();
  std::mt19937 rng(spec.seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  for (const Eigen::Vector3d& l : scene.stack.light_directions) {
    cv::Mat image;
    refl::RenderReflectance(t, l, Eigen::Vector3d::Ones(), Eigen::Vector3d::UnitZ(), &image);
    scene.clean.push_back(image.clone());
    float* v = image.ptr<float>();
    for (std::size_t i = 0; i < image.total() * C; ++i) {
      const double sigma = std::sqrt(spec.read_sigma * spec.read_sigma +
                                     spec.shot_fraction * spec.shot_fraction * std::max(0.0f, v[i]) * std::max(0.0f, v[i]));
      v[i] = static_cast<float>(v[i] + sigma * gauss(rng));
    }
    scene.stack.images.push_back(image);
  }
  return scene;
}

// The true normals tilted by `tilt_deg` in a random direction per pixel of
// the object: photometric stereo's error, in size if not in structure.
inline cv::Mat TiltedNormals(const SvbrdfScene& scene, double tilt_deg, unsigned seed) {
  cv::Mat out = scene.truth.normals.clone();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> azimuth(0.0, 2.0 * M_PI);
  for (int i = 0; i < static_cast<int>(out.total()); ++i) {
    if (!scene.mask.data[i]) continue;
    const cv::Vec3f& v = out.at<cv::Vec3f>(i);
    const Eigen::Vector3d n(v[0], v[1], v[2]);
    const Eigen::Vector3d a = std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
    const Eigen::Vector3d t = a.cross(n).normalized(), b = n.cross(t);
    const double phi = azimuth(rng), tilt = tilt_deg * M_PI / 180.0;
    const Eigen::Vector3d m = std::cos(tilt) * n + std::sin(tilt) * (std::cos(phi) * t + std::sin(phi) * b);
    out.at<cv::Vec3f>(i) = cv::Vec3f(static_cast<float>(m.x()), static_cast<float>(m.y()), static_cast<float>(m.z()));
  }
  return out;
}

// Mean angle (degrees) to the true normals over the scene's object.
inline double MeanNormalErrorDeg(const SvbrdfScene& scene, const cv::Mat& normals) {
  double sum = 0.0;
  int count = 0;
  for (int i = 0; i < static_cast<int>(scene.mask.total()); ++i) {
    if (!scene.mask.data[i]) continue;
    const cv::Vec3f& a = normals.at<cv::Vec3f>(i);
    const cv::Vec3f& b = scene.truth.normals.at<cv::Vec3f>(i);
    sum += std::acos(std::clamp(static_cast<double>(a.dot(b)) / (cv::norm(a) * cv::norm(b)), -1.0, 1.0)) * 180.0 / M_PI;
    ++count;
  }
  return sum / count;
}

// The three-material colour scene of the tests: matte, Blinn-Phong and GGX bands.
inline SceneSpec ThreeMaterials(int channels = 3) {
  SceneSpec spec;
  spec.channels = channels;
  spec.materials = {Matte(), Phong(0.35, 80.0), Ggx(0.25, 0.3)};
  spec.band_colour = {Eigen::Vector3d(0.9, 0.6, 0.4), Eigen::Vector3d(0.4, 0.7, 0.9), Eigen::Vector3d(0.7, 0.9, 0.5)};
  return spec;
}

}  // namespace photorig::testing
