#pragma once
// WriteGltfAsset's asset before it is written (gltf_export.h): the glTF model
// with its buffer's bytes in memory, and the images it writes beside it.
// Internal to photorig_daemon_io; the glTF round-trip fuzzer reads it to
// check the model through tinygltf's JSON in memory, without the files.

#include "photorig/solvers/camera/camera.h"
#include "photorig/solvers/reflectance/fit.h"
#include "tinygltf_config.h"

#include <opencv2/core.hpp>

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace photorig::daemon::internal {

struct GltfModel {
  // buffers[0] is asset.bin; images name the PNGs of `png` by file name.
  tinygltf::Model model;
  // File name and image: 8-bit RGB PNGs (the glTF's textures and normal.png)
  // and float EXRs (RGB or one channel), in the order they are written.
  std::vector<std::pair<std::string, cv::Mat>> png, exr;
  std::size_t vertices = 0, triangles = 0;
};

// The model and images of WriteGltfAsset's asset. Throws std::runtime_error
// "no fitted pixel has a depth" when the mesh would be empty.
GltfModel BuildGltfModel(const solvers::reflectance::ReflectanceMaps& maps, const cv::Mat& depth,
                         const solvers::camera::PixelRays& rays);

}  // namespace photorig::daemon::internal
