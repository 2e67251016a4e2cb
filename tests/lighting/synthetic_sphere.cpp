#include "synthetic_sphere.h"

#include <Eigen/Geometry>

#include <cmath>
#include <random>

namespace photorig::solvers::lighting::testing {
namespace {

// Camera-frame ray origin and direction through image point (u, v).
void PixelRay(const SyntheticCamera& camera, const SyntheticImageOptions& options, double u, double v,
              Eigen::Vector3d* origin, Eigen::Vector3d* direction) {
  if (camera.pinhole) {
    *origin = Eigen::Vector3d::Zero();
    *direction = Eigen::Vector3d((u - camera.cx_px) / camera.fx_px, -(v - camera.cy_px) / camera.fy_px, -1.0).normalized();
  } else {
    *origin = Eigen::Vector3d((u - (options.width - 1) / 2.0) * camera.pixel_pitch_mm,
                              -(v - (options.height - 1) / 2.0) * camera.pixel_pitch_mm, 1e4);
    *direction = Eigen::Vector3d(0, 0, -1);
  }
}

bool Hit(const SyntheticSphere& sphere, const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
         Eigen::Vector3d* point) {
  const Eigen::Vector3d oc = origin - sphere.centre_mm;
  const double b = oc.dot(direction);
  const double disc = b * b - oc.squaredNorm() + sphere.radius_mm * sphere.radius_mm;
  if (disc < 0.0) return false;
  *point = origin + (-b - std::sqrt(disc)) * direction;
  return true;
}

// Supersamples only pixels whose corners disagree (silhouette) or that carry
// more than `detail` of signal (a highlight); elsewhere one central sample is exact enough.
template <typename Shade>
cv::Mat Render(const SyntheticCamera& camera, const SyntheticSphere& sphere, const SyntheticImageOptions& options,
               int channels, double detail, Shade shade) {
  cv::Mat image(options.height, options.width, CV_MAKETYPE(CV_32F, channels), cv::Scalar::all(0));
  const auto sample = [&](double u, double v, bool* hit) {
    Eigen::Vector3d origin, direction, point;
    PixelRay(camera, options, u, v, &origin, &direction);
    *hit = Hit(sphere, origin, direction, &point);
    return *hit ? Eigen::Vector3d(shade(point, (point - sphere.centre_mm).normalized(), -direction))
                : Eigen::Vector3d::Zero();
  };
  const int s = options.supersample;
#pragma omp parallel for schedule(dynamic, 4)
  for (int r = 0; r < options.height; ++r) {
    for (int c = 0; c < options.width; ++c) {
      {  // Far from the sphere (more than a tenth of its radius): background, one test.
        Eigen::Vector3d origin, direction;
        PixelRay(camera, options, c, r, &origin, &direction);
        const Eigen::Vector3d oc = sphere.centre_mm - origin;
        if ((oc - oc.dot(direction) * direction).norm() > 1.1 * sphere.radius_mm) continue;
      }
      bool hit = false, corner_hit = false, mixed = false;
      Eigen::Vector3d sum = sample(c, r, &hit);
      double largest = sum.maxCoeff();
      for (int corner = 0; corner < 4; ++corner) {
        largest = std::max(largest, sample(c - 0.5 + (corner & 1), r - 0.5 + (corner >> 1), &corner_hit).maxCoeff());
        mixed = mixed || corner_hit != hit;
      }
      if (mixed || largest > detail) {
        sum.setZero();
        for (int i = 0; i < s; ++i) {
          for (int j = 0; j < s; ++j) sum += sample(c - 0.5 + (j + 0.5) / s, r - 0.5 + (i + 0.5) / s, &corner_hit);
        }
        sum /= s * s;
      }
      for (int k = 0; k < channels; ++k) image.ptr<float>(r)[c * channels + k] = static_cast<float>(sum(channels == 3 ? 2 - k : 0));
    }
  }
  return image;
}

// Background, noise and clipping for every channel of every pixel (the image
// is continuous: Render made it).
void Finish(cv::Mat* image, const SyntheticImageOptions& options) {
  std::mt19937 rng(options.seed);
  std::normal_distribution<float> noise(0.0f, static_cast<float>(options.noise_sigma));
  float* values = image->ptr<float>();
  for (std::size_t i = 0; i < image->total() * image->channels(); ++i) {
    float v = values[i] + static_cast<float>(options.background);
    if (options.noise_sigma > 0.0) v += noise(rng);
    values[i] = std::clamp(v, 0.0f, static_cast<float>(options.saturation));
  }
}

}  // namespace

Eigen::Vector2d OrthographicPixel(const SyntheticCamera& camera, const SyntheticImageOptions& options, double x_mm,
                                  double y_mm) {
  return {x_mm / camera.pixel_pitch_mm + (options.width - 1) / 2.0, -y_mm / camera.pixel_pitch_mm + (options.height - 1) / 2.0};
}

cv::Mat RenderSilhouette(const SyntheticCamera& camera, const SyntheticSphere& sphere, const SyntheticImageOptions& options) {
  return Render(camera, sphere, options, 1, HUGE_VAL,
                [](const Eigen::Vector3d&, const Eigen::Vector3d&, const Eigen::Vector3d&) {
                  return Eigen::Vector3d::Constant(1000.0);
                });
}

cv::Mat RenderMirrorSphere(const SyntheticCamera& camera, const SyntheticSphere& sphere,
                           const std::vector<SyntheticLight>& lights, const SyntheticImageOptions& options) {
  cv::Mat image = Render(camera, sphere, options, 1, 0.1,
                         [&](const Eigen::Vector3d& p, const Eigen::Vector3d& n, const Eigen::Vector3d& w_o) {
                           const Eigen::Vector3d reflected = 2.0 * n.dot(w_o) * n - w_o;
                           double value = 0.0;
                           for (const auto& light : lights) {
                             const Eigen::Vector3d l = light.near ? (light.position_mm - p).normalized()
                                                                  : light.direction.normalized();
                             const double angle = AngleDeg(reflected, l);
                             value += light.peak * std::exp(-0.5 * std::pow(angle / light.angular_sigma_deg, 2));
                           }
                           return Eigen::Vector3d::Constant(value);
                         });
  Finish(&image, options);
  return image;
}

cv::Mat RenderWhiteSphere(const SyntheticCamera& camera, const SyntheticSphere& sphere, const Eigen::Vector3d& light,
                          const Eigen::Vector3d& rgb, const SyntheticImageOptions& options, double sheen,
                          double sheen_exponent) {
  const Eigen::Vector3d l = light.normalized();
  cv::Mat image = Render(camera, sphere, options, 3, HUGE_VAL,
                         [&](const Eigen::Vector3d&, const Eigen::Vector3d& n, const Eigen::Vector3d& w_o) {
                           const double cosine = std::max(0.0, n.dot(l));
                           const double lobe = sheen * (sheen_exponent + 2.0) / (2.0 * M_PI) *
                                               std::pow(std::max(0.0, n.dot((l + w_o).normalized())), sheen_exponent);
                           return Eigen::Vector3d(rgb * (1.0 / M_PI + lobe) * cosine);
                         });
  Finish(&image, options);
  return image;
}

cv::Mat WhiteSphereScene::Render(const Eigen::Vector3d& light, const Eigen::Vector3d& rgb, double sheen,
                                 double sheen_exponent) const {
  return RenderWhiteSphere(camera, sphere, light, rgb, options, sheen, sheen_exponent);
}

WhiteSphereScene MakeWhiteSphereScene(double radius_px, int size_px, double noise_sigma, int supersample) {
  WhiteSphereScene scene;
  scene.sphere.radius_mm = radius_px * scene.camera.pixel_pitch_mm;
  scene.options.width = scene.options.height = size_px;
  scene.options.supersample = supersample;
  scene.options.background = 0.0;
  scene.options.noise_sigma = noise_sigma;
  scene.geometry =
      LocateSphere(CameraModel{}, FitSphereSilhouette(RenderSilhouette(scene.camera, scene.sphere, scene.options)).circle);
  return scene;
}

void SphereNormals(int size_px, double radius_fraction, cv::Mat* normals, cv::Mat* mask) {
  *normals = cv::Mat(size_px, size_px, CV_32FC3, cv::Scalar::all(0));
  *mask = cv::Mat(size_px, size_px, CV_8U, cv::Scalar(0));
  const double centre = (size_px - 1) / 2.0, radius = radius_fraction * size_px / 2.0;
  for (int r = 0; r < size_px; ++r) {
    for (int c = 0; c < size_px; ++c) {
      const double x = (c - centre) / radius, y = -(r - centre) / radius;
      if (x * x + y * y >= 1.0) continue;
      normals->at<cv::Vec3f>(r, c) = cv::Vec3f(static_cast<float>(x), static_cast<float>(y),
                                               static_cast<float>(std::sqrt(1.0 - x * x - y * y)));
      mask->at<std::uint8_t>(r, c) = 255;
    }
  }
}

std::vector<Eigen::Vector3d> DomeDirections() {
  std::vector<Eigen::Vector3d> directions;
  const std::pair<double, int> rings[] = {{25, 16}, {45, 14}, {65, 12}, {80, 6}};
  for (const auto& [elevation, count] : rings) {
    for (int i = 0; i < count; ++i) {
      const double e = elevation * M_PI / 180.0, a = 2.0 * M_PI * (i + 0.3 * (elevation > 40)) / count;
      directions.emplace_back(std::cos(e) * std::cos(a), std::cos(e) * std::sin(a), std::sin(e));
    }
  }
  return directions;
}

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI;
}

}  // namespace photorig::solvers::lighting::testing
