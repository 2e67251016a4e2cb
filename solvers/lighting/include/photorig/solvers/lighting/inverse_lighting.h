#pragma once
// Inverse lighting: from normals, albedo and one photo under unknown distant
// lighting, estimate that lighting as spherical harmonics (band chosen by what
// the data support) or as non-negative weights over the dome's LED directions.
// Image model (Lambertian, no cast shadows): I = albedo / pi * E(n).

#include "photorig/solvers/core/summary.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace photorig::solvers::lighting {

struct ShFitOptions {
  enum class Selection {
    kHeldOut,  // two-fold cross-validated residual; the lowest band within heldout_tolerance of the best
    kBic,      // Bayesian information criterion
    kFixed     // always fixed_band
  };
  Selection selection = Selection::kHeldOut;
  int max_band = 4;           // candidates 0, 1, 2, 4 up to this (band 3 is invisible to a Lambertian surface)
  int fixed_band = 2;
  double heldout_tolerance = 0.01;  // relative
  int pixel_stride = 1;       // use every n-th pixel in both directions
  double min_albedo = 1e-3;
  // The fit pins the lighting down on the normals it sees; towards the rest
  // of the visible hemisphere it extrapolates. Above this predicted relative
  // uncertainty there (ShLightingSummary::hemisphere_relative_sigma) the
  // summary's message says so: relighting other normals, or reading the
  // lighting as the environment's, would carry that error.
  double max_hemisphere_relative_sigma = 0.05;

  bool IsValid(std::string* why) const;
};

struct ShCandidate {
  int band = 0;
  double train_rms = 0.0;
  double heldout_rms = 0.0;
  double bic = 0.0;
};

struct ShLightingSummary : solvers::core::Summary {
  int band = 0;
  // Radiance coefficients L_lm, ShCoefficientCount(band) rows x channels (R, G, B for colour images).
  // Odd bands above 1 are not observable through a Lambertian surface and are zero.
  Eigen::MatrixXd coefficients;
  std::vector<ShCandidate> candidates;
  double rms_residual = 0.0;
  double relative_rms_residual = 0.0;  // rms / mean intensity
  double condition_number = 0.0;
  // One sigma of the fitted irradiance (first channel) at the worst normal of
  // the visible hemisphere (z >= 0), from the coefficients' covariance (the
  // residual variance times the inverse normal matrix), over the mean
  // fitted irradiance there. Small when the normals seen span the hemisphere;
  // large when they are a narrow cap.
  double hemisphere_relative_sigma = 0.0;
  std::size_t pixels_used = 0;
};

// normals CV_32FC3 (x, y, z per pixel), albedo CV_32FC1 or same channels as image,
// image CV_32F 1 or 3 channels, mask CV_8U (empty: every pixel).
ShLightingSummary FitShLighting(const cv::Mat& normals, const cv::Mat& albedo, const cv::Mat& image,
                                const cv::Mat& mask, const ShFitOptions& options = {});

struct LedWeightsOptions {
  int pixel_stride = 1;
  double min_albedo = 1e-3;
  // Drive no more LEDs than the image supports: from the non-negative least
  // squares, LEDs are dropped one at a time (the one whose loss costs least,
  // the rest refitted) while the rise of the sum of squares stays below the
  // Bayesian information criterion's price of one parameter, ln(pixels)
  // times the fit's residual variance. Off: every LED the least squares
  // drives, where noise spreads a few LEDs' light over their neighbours.
  bool simplest_led_set = true;
  bool IsValid(std::string* why) const;
};

struct LedWeightsSummary : solvers::core::Summary {
  Eigen::MatrixXd weights;  // LEDs x channels (R, G, B for colour), drive levels >= 0 relative to each LED's calibrated intensity
  double rms_residual = 0.0;
  double relative_rms_residual = 0.0;
  int active_leds = 0;  // weights above 1e-4 of the largest
  int leds_dropped = 0;  // by simplest_led_set, summed over the channels
  std::size_t pixels_used = 0;
};

LedWeightsSummary FitLedWeights(const cv::Mat& normals, const cv::Mat& albedo, const cv::Mat& image,
                                const cv::Mat& mask, const std::vector<Eigen::Vector3d>& led_directions,
                                const std::vector<double>& led_intensities, const LedWeightsOptions& options = {});

}  // namespace photorig::solvers::lighting
