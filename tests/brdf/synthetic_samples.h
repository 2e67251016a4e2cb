#pragma once
// Measured-looking BRDF samples of a known model, for the fit tests and the bench.

#include "photorig/solvers/brdf/models.h"
#include "photorig/solvers/brdf/samples.h"

#include <cstdint>
#include <vector>

namespace photorig::solvers::brdf::testing {

struct SyntheticSpec {
  int count = 300;
  double theta_h_min_deg = 0.0, theta_h_max_deg = 60.0;  // where the configurations fall, uniform in theta_h
  double theta_d_max_deg = 75.0;                          // uniform in theta_d, phi_d in [0, 2 pi)
  // Gaussian noise of sd relative_sigma * f + absolute_sigma (1/sr), which
  // the samples carry as their sigma.
  double relative_sigma = 0.02;
  double absolute_sigma = 0.002;
  std::uint32_t seed = 1;
};

// Configurations below the horizon are drawn again, so there are always `count`.
std::vector<BrdfSample> SyntheticSamples(const ModelParams& truth, const SyntheticSpec& spec);

// The charts' error of a fit: relative RMS of f_r cos theta_i against the
// truth over held-out configurations, all channels together.
double RelativeError(const ModelParams& fit, const ModelParams& truth, const std::vector<BrdfSample>& held_out);

}  // namespace photorig::solvers::brdf::testing
