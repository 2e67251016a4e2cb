#pragma once
// One measured BRDF value: the configuration and what was measured there; and
// the CSV file such samples are kept in.

#include "photorig/solvers/core/summary.h"

#include <Eigen/Core>

#include <optional>
#include <string>
#include <vector>

namespace photorig::solvers::brdf {

// Where a measured sample was taken, so a stored sample can be traced back to
// its frames and re-measured.
struct SampleOrigin {
  double light_arm_deg = 0.0;
  double camera_arm_deg = 0.0;
  double sample_rotation_deg = 0.0;
  // The longest exposure merged into the value: with inverse-variance weights
  // it carries most of the weight. Shorter exposures of a bracket enter only
  // where the longer ones clip.
  double exposure_us = 0.0;
  int frames = 0;  // frames merged into the value (repeats over the exposures used)
};

struct BrdfSample {
  Eigen::Vector3d wi = Eigen::Vector3d::UnitZ();  // towards the light, sample frame (normal = z), unit
  Eigen::Vector3d wo = Eigen::Vector3d::UnitZ();  // towards the camera, unit
  // f_r in 1/sr per channel (R, G, B): the BRDF itself, not the cosine-weighted
  // reflected radiance L / E = f_r cos theta_i.
  Eigen::Vector3d value = Eigen::Vector3d::Zero();
  // Standard deviation of `value` per channel, 1/sr; 0 when not known.
  Eigen::Vector3d sigma = Eigen::Vector3d::Zero();
  // The sample's weight in the fit's loss (its squared residuals are
  // multiplied by it): 1 for a measured sample; for a cell drawn from a table
  // at random, the inverse of its drawing density (mean 1), so that the loss
  // estimates the loss over every cell (table_fit.h). Not kept in samples.csv.
  double weight = 1.0;
  std::optional<SampleOrigin> origin;  // absent for samples drawn from a table or a model
};

// The sample file of `photorig solve brdf` (samples.csv): a header line, then
// per sample wi_x,wi_y,wi_z,wo_x,wo_y,wo_z,f_r,f_g,f_b,sigma_r,sigma_g,sigma_b,
// light_arm_deg,camera_arm_deg,sample_rotation_deg,exposure_us,frames; the
// last five are empty for a sample without an origin.
core::Summary WriteSamplesCsv(const std::string& path, const std::vector<BrdfSample>& samples);
// Reads that file, and the earlier one without the origin columns. A missing
// header, a line that is not 12 numbers followed (in the newer file) by five
// numbers or five empty cells ends kInvalidInput naming the file and line;
// `samples` is then untouched.
core::Summary ReadSamplesCsv(const std::string& path, std::vector<BrdfSample>* samples);

}  // namespace photorig::solvers::brdf
