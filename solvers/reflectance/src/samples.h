#pragma once
// The stack's samples gathered per pixel in a local frame (normal = z), and
// the linear least squares every method shares: for a fixed lobe shape the
// radiance is linear in the pixel's albedo rho and the material's specular
// weight s,
//   I = u rho + g + h s,  u = E cos_i / pi,  g + h s = E cos_i lobe(s)
// (g = 0 for Blinn-Phong; GGX's Schlick term is affine in F0), so the
// albedos are eliminated exactly per pixel and s solved from the remainder.

#include "photorig/solvers/brdf/models.h"
#include "photorig/solvers/reflectance/fit.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <vector>

namespace photorig::solvers::reflectance::internal {

struct Samples {
  int pixels = 0, lights = 0, channels = 0;
  int width = 0, height = 0;
  std::vector<int> pixel_index;          // row * width + col, per gathered pixel
  std::vector<float> value;              // [pixel][light][channel]
  std::vector<float> weight;             // [pixel][light][channel]: 1 / noise variance (1 until WeightSamples)
  std::vector<std::uint8_t> usable;      // [pixel][light]: lit and unsaturated
  std::vector<std::uint8_t> saturated;   // [pixel][light]: lit and clipped
  // [pixel][light]: the cosines of the light and view directions in the
  // pixel's frame, computed once: every trial lobe shape reads them.
  std::vector<brdf::Geometry> geometry;
  std::vector<Eigen::Vector3d> normal;   // [pixel] in camera frame
  std::vector<Eigen::Vector3d> intensity;  // [light]
  // [pixel][light]: the factor on `intensity` where the stack has near LEDs
  // (ReflectanceStack::near_lights); empty under distant lights.
  std::vector<float> gain;
  std::vector<int> usable_count;         // [pixel]

  std::size_t At(int p, int j) const { return static_cast<std::size_t>(p) * lights + j; }
  // The irradiance of a cell's light at normal incidence, in channel ch.
  double Irradiance(std::size_t cell, int j, int ch) const {
    return intensity[j][ch] * (gain.empty() ? 1.0 : static_cast<double>(gain[cell]));
  }
};

// Where a stack's pixels see its lights and camera from
// (ReflectanceStack::near_lights, views), with the LEDs' constants worked
// out once.
class PixelLights {
 public:
  explicit PixelLights(const ReflectanceStack& stack);
  // Light j seen from pixel `index` (row * width + col): the unit vector
  // towards it, and the factor on Intensity(j) (1 under distant lights).
  double At(int index, int j, Eigen::Vector3d* towards) const;
  // The unit vector from pixel `index` towards the camera.
  Eigen::Vector3d View(int index) const;

 private:
  const ReflectanceStack& stack_;
  std::vector<camera::PreparedNearLight> near_;
};

// Gathers every masked pixel with a finite normal facing the camera; the
// others are flagged in *flags (CV_8U, same size as the stack).
Samples Gather(const ReflectanceStack& stack, const cv::Mat& normals, const cv::Mat& mask, double min_cosine,
               cv::Mat* flags, long long* saturated_samples);

struct Lobe {
  brdf::Model model = brdf::Model::kLambertian;
  double shape = 0.0;
};

// Lobe values of s = 0 and s = 1 (per unit irradiance, without the cosine).
void LobeBasis(const Lobe& lobe, const brdf::Geometry& g, double* a0, double* a1);

// The per-pixel normal-equation sums of one channel.
struct ChannelSums {
  double uu = 0, uh = 0, hh = 0, uy = 0, hy = 0, yy = 0;
};
struct PixelSums {
  ChannelSums c[3];
  int samples = 0;
};
// `enabled`: per light, 0 leaves it out (held-out evaluation); empty = all.
PixelSums SumsOf(const Samples& s, int p, const Lobe& lobe, const std::vector<std::uint8_t>& enabled);

// The pixel's albedo (clamped >= 0) and squared residual given the weight.
double PixelCost(const ChannelSums& sums, double weight, double* rho);

struct GroupFit {
  Eigen::Vector3d weight = Eigen::Vector3d::Zero();
  Eigen::Vector3d reduced_hh = Eigen::Vector3d::Zero();  // the weight's normal-equation coefficient
  // The weight's variance with pixels as the independent units (a
  // cluster-robust sandwich): a pixel's samples share its normal's and its
  // demosaicing's errors, which the per-sample noise model does not know.
  Eigen::Vector3d weight_variance = Eigen::Vector3d::Zero();
  double cost = 0.0;
  long long residuals = 0;
};
// Shared weight per channel and total cost over `pixels` at one lobe shape.
GroupFit FitGroup(const Samples& s, const std::vector<int>& pixels, const Lobe& lobe,
                  const std::vector<std::uint8_t>& enabled, std::vector<PixelSums>* sums_out = nullptr);

// The lobe shape minimising the group's cost: a log-spaced grid, then golden
// section between the best point's neighbours (`refine` = false: grid only).
struct ShapeSearch {
  double shape = 0.0;
  double cost = 0.0;
  double log_shape_sigma = 0.0;  // from the cost's curvature in log(shape)
};
ShapeSearch SearchShape(const Samples& s, const std::vector<int>& pixels, brdf::Model model,
                        const std::vector<std::uint8_t>& enabled, bool refine);
const std::vector<double>& ShapeGrid(brdf::Model model);

// Full fit of one material over `pixels` with each candidate lobe; the one of
// least BIC is kept (`candidates` includes kLambertian).
struct MaterialResult {
  MaterialFit fit;
  double cost = 0.0;
  long long residuals = 0;
};
MaterialResult FitMaterial(const Samples& s, const std::vector<int>& pixels, const std::vector<brdf::Model>& candidates,
                           const std::vector<std::uint8_t>& enabled, int search_pixels);

// Radiance of one cell (pixel, light; Samples::At) with albedo rho and a lobe.
double Predict(const Samples& s, std::size_t cell, const Lobe& lobe, double weight, double rho, double irradiance);

// An orthonormal frame (t, b, n) with n as its z axis.
void FrameOf(const Eigen::Vector3d& n, Eigen::Vector3d* t, Eigen::Vector3d* b);
// w in the frame of normal n (FrameOf).
Eigen::Vector3d ToLocal(const Eigen::Vector3d& n, const Eigen::Vector3d& w);

}  // namespace photorig::solvers::reflectance::internal

namespace photorig::solvers::reflectance::internal {

// Each pixel's own Blinn-Phong lobe (exponent from the grid, weight and
// albedo per channel), or none where no lobe lowers its cost.
struct PixelLobe {
  double exponent = 0.0;
  Eigen::Vector3d weight = Eigen::Vector3d::Zero();
  Eigen::Vector3d rho = Eigen::Vector3d::Zero();
};
std::vector<PixelLobe> FitPixelLobes(const Samples& s, const std::vector<int>& pixels,
                                     const std::vector<std::uint8_t>& enabled, const core::ProgressCallback& progress);

// Per-pixel Lambertian albedo.
std::vector<Eigen::Vector3d> FitLambertian(const Samples& s, const std::vector<int>& pixels,
                                           const std::vector<std::uint8_t>& enabled);

// The noise model to weight by: what `given` knows, the rest estimated from
// the residuals of each pixel's own lobe (`own`, index-aligned with `pixels`).
// *source says which ("given", "estimated", "read noise given, shot noise estimated").
SensorNoise EstimateNoise(const Samples& s, const std::vector<int>& pixels, const std::vector<PixelLobe>& own,
                          const SensorNoise& given, std::string* source);

// Weights every sample of `pixels` by 1 / variance at its pixel's own-lobe
// prediction (a smooth signal: a weight taken from the noisy sample itself
// would favour the samples that noise pulled down).
void WeightSamples(const SensorNoise& noise, const std::vector<int>& pixels, const std::vector<PixelLobe>& own,
                   Samples* s);

// Albedos of `pixels` under a material's lobe and weights.
std::vector<Eigen::Vector3d> FitAlbedo(const Samples& s, const std::vector<int>& pixels, const MaterialFit& material,
                                       const std::vector<std::uint8_t>& enabled);

}  // namespace photorig::solvers::reflectance::internal
