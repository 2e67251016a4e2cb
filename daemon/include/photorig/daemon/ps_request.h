#pragma once
// The `photometric_stereo:` stage of a recipe's solve pipeline, and the same
// settings as given on the command line.

#include "photorig/daemon/rig_config.h"

#include <string>

namespace photorig::daemon {

struct PhotometricStereoRequest {
  std::string method = "auto";          // l2 | lambertian | robust | blinn-phong | auto
  // Samples within this many read-noise sigmas of black (and within 1 DN) are
  // shadows; the read noise comes from dark frames, or is estimated without them.
  double shadow_threshold_sigma = 3.0;
  double max_condition_number = 1e3;
  // Blinn-Phong fit: lanes (closed-form derivatives, sixteen pixels per SIMD
  // pass in float) | forward | reverse | symbolic | central-difference (one pixel at a
  // time, Jacobians by that method).
  std::string derivative = "lanes";
  std::string integrator = "poisson";   // depth from normals: poisson | frankot-chellappa | none
};

// Throws ConfigError naming file:line:column for unknown keys or values.
PhotometricStereoRequest ParsePhotometricStereoRequest(const YamlNode& node);
// Throws std::invalid_argument naming the field when a value is not allowed.
void ValidatePhotometricStereoRequest(const PhotometricStereoRequest& request);

}  // namespace photorig::daemon
