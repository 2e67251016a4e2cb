#pragma once
// Relative light intensities from a diffuse white target (sphere or plane) of
// known geometry, lit by lights of known direction: I = albedo / pi * E * (n . l).

#include "photorig/solvers/lighting/sphere.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace photorig::solvers::lighting {

struct DiffuseIntensityOptions {
  double albedo = 1.0;             // of the white target
  double min_cosine = 0.25;        // samples with n . l below this are left out (grazing, shadow edge)
  double max_radius_fraction = 0.9;  // sphere: pixels beyond this fraction of the radius are left out
  double saturation_level = -1.0;  // samples at or above are left out; negative: none
  int min_samples = 50;
  // The largest model_error (LightIntensityEstimate) a usable estimate may
  // have: the target's shading departs from albedo / pi E (n . l) by more
  // than this fraction of the mean sample beyond what the noise explains (a
  // glossy or shadowed target, an interreflection, a sphere out of place).
  double max_model_error = 0.05;

  bool IsValid(std::string* why) const;
};

struct LightIntensityEstimate {
  bool usable = false;
  Eigen::Vector3d rgb{0, 0, 0};    // irradiance per channel (R, G, B); grey images give equal channels
  double relative_rms_residual = 0.0;  // of the Lambertian fit, relative to the mean sample
  // The image noise's RMS relative to the mean sample, estimated from the
  // fit's residuals' differences between horizontally adjacent samples
  // (where the shading the fit misses cancels and the noise does not; sensor
  // noise and 8-bit rounding alike), and the residuals' RMS beyond it:
  // sqrt(max(0, rms^2 - noise^2 - 3 SE)) / mean, the worst channel's, SE the
  // standard error of rms^2 - noise^2 from the samples. NaN with too few
  // adjacent samples to tell (then not tested).
  double relative_noise_rms = 0.0;
  double model_error = 0.0;
  int samples_used = 0;
  int samples_saturated = 0;
  std::string note;
};

// image: 1 or 3 channels (BGR as OpenCV stores it), any depth, linear.
LightIntensityEstimate EstimateIntensityFromSphere(const cv::Mat& image, const SphereGeometry& sphere,
                                                   const Eigen::Vector3d& light_direction,
                                                   const DiffuseIntensityOptions& options = {});
// A plane of normal `plane_normal`; mask (CV_8U, may be empty) selects the target pixels.
LightIntensityEstimate EstimateIntensityFromPlane(const cv::Mat& image, const cv::Mat& mask,
                                                  const Eigen::Vector3d& plane_normal,
                                                  const Eigen::Vector3d& light_direction,
                                                  const DiffuseIntensityOptions& options = {});

// Scales usable estimates so that their mean (over lights and channels) is 1.
void NormaliseIntensities(std::vector<LightIntensityEstimate>* estimates);

}  // namespace photorig::solvers::lighting
