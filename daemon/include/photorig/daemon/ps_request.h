#pragma once
// The `photometric_stereo:` stage of a recipe's solve pipeline, and the same
// settings as given on the command line.

#include "photorig/daemon/yaml_node.h"

#include <string>

namespace photorig::daemon {

struct PhotometricStereoRequest {
  std::string method = "auto";          // l2 | lambertian | robust | blinn-phong | auto
  double shadow_threshold_sigma = 3.0;  // samples within this many dark-noise sigmas of black are shadows
  double max_condition_number = 1e3;
  // Blinn-Phong fit: lanes (closed-form derivatives, eight pixels per SIMD
  // pass) | forward | reverse | symbolic | central-difference (one pixel at a
  // time, Jacobians by that method).
  std::string derivative = "lanes";
  std::string integrator = "poisson";   // depth from normals: poisson | frankot-chellappa | none
};

// Throws ConfigError naming file:line:column for unknown keys or values.
PhotometricStereoRequest ParsePhotometricStereoRequest(const YamlNode& node);
// Throws std::invalid_argument naming the field when a value is not allowed.
void ValidatePhotometricStereoRequest(const PhotometricStereoRequest& request);

}  // namespace photorig::daemon
