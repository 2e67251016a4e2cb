#pragma once
// Analytic images of calibration spheres for the lighting tests, independent of
// the solver's own sphere geometry: a ray-sphere intersection per sub-sample.

#include "photorig/solvers/lighting/sphere.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <vector>

namespace photorig::solvers::lighting::testing {

struct SyntheticCamera {
  bool pinhole = false;
  double fx_px = 0.0, fy_px = 0.0, cx_px = 0.0, cy_px = 0.0;  // pinhole
  double pixel_pitch_mm = 0.1;                                 // orthographic: object-space pixel size
};

struct SyntheticSphere {
  Eigen::Vector3d centre_mm{0, 0, 0};  // orthographic: x, y give the image position via the pixel pitch
  double radius_mm = 10.0;
};

struct SyntheticLight {
  Eigen::Vector3d direction{0, 0, 1};  // distant light (used when !near)
  bool near = false;
  Eigen::Vector3d position_mm{0, 0, 0};
  double angular_sigma_deg = 0.8;      // mirror highlight lobe width
  double peak = 3000.0;
};

struct SyntheticImageOptions {
  int width = 400, height = 400;
  int supersample = 4;
  double background = 20.0;
  double saturation = 4095.0;
  double noise_sigma = 0.0;
  unsigned seed = 1;
};

// Orthographic pixel (u, v) of the camera-frame point (x, y).
Eigen::Vector2d OrthographicPixel(const SyntheticCamera& camera, const SyntheticImageOptions& options, double x_mm, double y_mm);

// Silhouette: coverage * 1000 over background 0.
cv::Mat RenderSilhouette(const SyntheticCamera& camera, const SyntheticSphere& sphere, const SyntheticImageOptions& options);
// Mirror sphere under a set of lights (their lobes add).
cv::Mat RenderMirrorSphere(const SyntheticCamera& camera, const SyntheticSphere& sphere,
                           const std::vector<SyntheticLight>& lights, const SyntheticImageOptions& options);
// Diffuse sphere of albedo 1: rgb / pi * max(0, n . l), BGR 3-channel.
// With sheen > 0, a Blinn-Phong lobe of that share of rgb and that exponent
// on top (a glossy target the Lambertian intensity fit must refuse).
cv::Mat RenderWhiteSphere(const SyntheticCamera& camera, const SyntheticSphere& sphere, const Eigen::Vector3d& light,
                          const Eigen::Vector3d& rgb, const SyntheticImageOptions& options, double sheen = 0.0,
                          double sheen_exponent = 1.0);

// A white sphere of radius `radius_px` at the centre of a square image of
// `size_px` without background, noise `noise_sigma` DN, as RenderWhiteSphere
// draws it; `geometry` is where the solver places it from its silhouette.
struct WhiteSphereScene {
  SyntheticCamera camera;
  SyntheticSphere sphere;
  SyntheticImageOptions options;
  SphereGeometry geometry;
  // RenderWhiteSphere of this scene.
  cv::Mat Render(const Eigen::Vector3d& light, const Eigen::Vector3d& rgb, double sheen = 0.0,
                 double sheen_exponent = 1.0) const;
};
WhiteSphereScene MakeWhiteSphereScene(double radius_px, int size_px, double noise_sigma, int supersample = 2);

// Orthographic sphere filling a square image: normals (CV_32FC3, zero outside) and mask.
void SphereNormals(int size_px, double radius_fraction, cv::Mat* normals, cv::Mat* mask);

// Directions of a dome of rings (elevation degrees, count per ring) like the sim rig's.
std::vector<Eigen::Vector3d> DomeDirections();

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b);

}  // namespace photorig::solvers::lighting::testing
