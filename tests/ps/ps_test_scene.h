#pragma once
// Synthetic photometric-stereo stacks with exactly known answers.

#include "photorig/solvers/ps/stack.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include <cmath>
#include <random>
#include <utility>
#include <vector>

namespace photorig::solvers::ps::testing {

// Lights on a cone of the given elevation band around +z.
inline std::vector<Eigen::Vector3d> RingLights(int count, double min_elevation_deg, double max_elevation_deg,
                                               unsigned seed = 3) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> elevation(min_elevation_deg * M_PI / 180, max_elevation_deg * M_PI / 180);
  std::vector<Eigen::Vector3d> lights;
  for (int i = 0; i < count; ++i) {
    const double az = 2 * M_PI * i / count, el = elevation(rng);
    lights.emplace_back(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
  }
  return lights;
}

struct TruthMaps {
  cv::Mat normals;  // CV_32FC3
  cv::Mat albedo;   // CV_32F
};

// Random normals within `max_tilt_deg` of +z, random albedo in [0.2, 0.9].
inline TruthMaps RandomSurface(int width, int height, double max_tilt_deg, unsigned seed = 7) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  TruthMaps truth{cv::Mat(height, width, CV_32FC3), cv::Mat(height, width, CV_32F)};
  const double max_tilt = max_tilt_deg * M_PI / 180;
  for (int r = 0; r < height; ++r)
    for (int c = 0; c < width; ++c) {
      const double tilt = std::acos(1 - unit(rng) * (1 - std::cos(max_tilt))), az = 2 * M_PI * unit(rng);
      truth.normals.at<cv::Vec3f>(r, c) =
          cv::Vec3f(std::sin(tilt) * std::cos(az), std::sin(tilt) * std::sin(az), std::cos(tilt));
      truth.albedo.at<float>(r, c) = static_cast<float>(0.2 + 0.7 * unit(rng));
    }
  return truth;
}

// I_k = dark + scale_k * albedo / pi * max(0, n . w_k), clipped at `saturation`.
inline PhotometricStack RenderStack(const TruthMaps& truth, const std::vector<Eigen::Vector3d>& lights,
                                    const std::vector<double>& scales, float dark_level,
                                    float saturation = INFINITY) {
  PhotometricStack stack;
  stack.light_directions = lights;
  stack.light_scales = scales;
  stack.dark = cv::Mat(truth.albedo.size(), CV_32F, cv::Scalar(dark_level));
  for (std::size_t k = 0; k < lights.size(); ++k) {
    cv::Mat image(truth.albedo.size(), CV_32F);
    for (int r = 0; r < image.rows; ++r)
      for (int c = 0; c < image.cols; ++c) {
        const cv::Vec3f n = truth.normals.at<cv::Vec3f>(r, c);
        const double cosine = std::max(0.0, n[0] * lights[k].x() + n[1] * lights[k].y() + n[2] * lights[k].z());
        const double value = dark_level + scales[k] * truth.albedo.at<float>(r, c) / M_PI * cosine;
        image.at<float>(r, c) = static_cast<float>(std::min<double>(value, saturation));
      }
    stack.images.push_back(image);
  }
  return stack;
}

// Angle between two stored normals; atan2 keeps small angles exact where acos
// of a float dot product cannot resolve them.
inline double AngleDeg(const cv::Vec3f& a, const cv::Vec3f& b) {
  const Eigen::Vector3d u(a[0], a[1], a[2]), v(b[0], b[1], b[2]);
  return std::atan2(u.cross(v).norm(), u.dot(v)) * 180.0 / M_PI;
}

}  // namespace photorig::solvers::ps::testing

namespace photorig::solvers::ps::testing {

struct Specular {
  double albedo = 0.0;    // rho_s
  double exponent = 1.0;  // e
};

// Diffuse + normalised Blinn-Phong, orthographic view (the unit vector
// `view` towards the camera, stored in the stack), written out independently
// of the solver's autodiff model:
//   I_k = dark + s_k [rho_d/pi + rho_s (e+2)/(2 pi) max(0, h.n)^e] max(0, n.w) + noise
inline PhotometricStack RenderShinyStack(const TruthMaps& truth, const std::vector<Eigen::Vector3d>& lights,
                                         double scale, Specular specular, float dark_level, double noise_sigma,
                                         unsigned seed = 11, const Eigen::Vector3d& view = Eigen::Vector3d::UnitZ()) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  PhotometricStack stack;
  stack.light_directions = lights;
  stack.light_scales.assign(lights.size(), scale);
  stack.dark = cv::Mat(truth.albedo.size(), CV_32F, cv::Scalar(dark_level));
  stack.noise.read_sigma = noise_sigma;
  stack.view_direction = view;
  for (const Eigen::Vector3d& w : lights) {
    const Eigen::Vector3d h = (w + view).normalized();
    cv::Mat image(truth.albedo.size(), CV_32F);
    for (int r = 0; r < image.rows; ++r)
      for (int c = 0; c < image.cols; ++c) {
        const cv::Vec3f nv = truth.normals.at<cv::Vec3f>(r, c);
        const Eigen::Vector3d n(nv[0], nv[1], nv[2]);
        const double cosine = std::max(0.0, n.dot(w));
        const double lobe = specular.albedo * (specular.exponent + 2) / (2 * M_PI) *
                            std::pow(std::max(0.0, h.dot(n)), specular.exponent);
        const double value = dark_level + scale * (truth.albedo.at<float>(r, c) / M_PI + lobe) * cosine;
        image.at<float>(r, c) = static_cast<float>(value + noise_sigma * gauss(rng));
      }
    stack.images.push_back(image);
  }
  return stack;
}

// The reference for the solver's per-pixel sums: least squares in double on
// pixel p's usable samples (I - D > shadow_threshold), b = (I - D) / s, for
// stacks with one scale s for every light and a uniform dark level.
struct UsableLeastSquares {
  int usable = 0;
  Eigen::Vector3d x = Eigen::Vector3d::Zero();
  double rss = 0.0;
  double sum_inverse_scale2 = 0.0, sum_signal_inverse_scale2 = 0.0;
};

inline UsableLeastSquares SolveUsableInDouble(const PhotometricStack& stack, int p, double scale, double dark,
                                              double shadow_threshold) {
  UsableLeastSquares out;
  Eigen::Matrix3d g = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  std::vector<std::pair<Eigen::Vector3d, double>> samples;
  for (int k = 0; k < stack.light_count(); ++k) {
    const double signal = double(stack.images[k].ptr<float>()[p]) - dark;
    if (!(signal > shadow_threshold)) continue;
    const Eigen::Vector3d& w = stack.light_directions[k];
    samples.emplace_back(w, signal / scale);
    g += w * w.transpose();
    rhs += w * (signal / scale);
    out.sum_inverse_scale2 += 1.0 / (scale * scale);
    out.sum_signal_inverse_scale2 += signal / (scale * scale);
  }
  out.usable = static_cast<int>(samples.size());
  if (out.usable < 3) return out;
  out.x = g.ldlt().solve(rhs);
  for (const auto& [w, b] : samples) out.rss += (b - w.dot(out.x)) * (b - w.dot(out.x));
  return out;
}

}  // namespace photorig::solvers::ps::testing
