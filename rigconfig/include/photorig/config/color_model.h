#pragma once
// A colour model file (photorig calibrate color's model.yaml or model.json) as
// a rig names it (camera.color_model), loaded and checked when the rig loads.

#include "photorig/solvers/color/model.h"

#include <string>

namespace photorig::config {

struct LoadedColorModel {
  std::string path;
  std::string content_hash;  // ContentHash of the file's bytes
  solvers::color::ColorModel model;
};

// Throws ConfigError with the file and, where the text says, the line and
// column of the key at fault. A model that is not exposure invariant (affine,
// polynomial) is refused: photometric stereo scales every frame by its own
// light, which only a model homogeneous of degree one commutes with.
LoadedColorModel LoadColorModelFile(const std::string& path);

// FNV-1a 64 of `bytes` as 16 hex digits: identifies a file in reports (not a
// defence against tampering).
std::string ContentHash(const std::string& bytes);

}  // namespace photorig::config
