#pragma once
// One measured BRDF value: the configuration and what was measured there; and
// the CSV file such samples are kept in.

#include "photorig/solvers/summary.h"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace photorig::solvers::brdf {

struct BrdfSample {
  Eigen::Vector3d wi = Eigen::Vector3d::UnitZ();  // towards the light, sample frame (normal = z), unit
  Eigen::Vector3d wo = Eigen::Vector3d::UnitZ();  // towards the camera, unit
  // f_r in 1/sr per channel (R, G, B): the BRDF itself, not the cosine-weighted
  // reflected radiance L / E = f_r cos theta_i.
  Eigen::Vector3d value = Eigen::Vector3d::Zero();
  // Standard deviation of `value` per channel, 1/sr; 0 when not known.
  Eigen::Vector3d sigma = Eigen::Vector3d::Zero();
};

// The sample file of `photorig solve brdf` (samples.csv): a header line, then
// per sample wi_x,wi_y,wi_z,wo_x,wo_y,wo_z,f_r,f_g,f_b,sigma_r,sigma_g,sigma_b.
Summary WriteSamplesCsv(const std::string& path, const std::vector<BrdfSample>& samples);
// A missing header or a line that is not 12 numbers ends kInvalidInput naming
// the file and line; `samples` is then untouched.
Summary ReadSamplesCsv(const std::string& path, std::vector<BrdfSample>* samples);

}  // namespace photorig::solvers::brdf
