#pragma once
// A relightable asset from a fitted reflectance: glTF 2.0 (tinygltf) with a
// mesh of the integrated depth and the textures of the fit, plus the maps as
// EXR (float) and PNG (8-bit) files beside it.
//
// Mesh: one vertex per fitted pixel with finite depth at ((c + 0.5) p,
// -(r + 0.5) p, depth) (as mesh_io.h), its fitted normal as NORMAL and
// TEXCOORD_0 = ((c + 0.5) / width, (r + 0.5) / height), so each vertex samples
// its own pixel's texels. Material (metallic = 0, see gltf_material.h):
//   base_colour.png        rho_d / (1 - F0), sRGB-encoded as glTF requires
//   metallic_roughness.png G = roughness, B = metallic (0)
//   specular_colour.png    KHR_materials_specular specularColorTexture, F0 / 0.04 / 25
//                          (specularColorFactor = 25, so every F0 up to 1 is representable)
//   normal.png             the fitted normals in camera space, (n + 1) / 2 (not referenced
//                          by the glTF, whose normal maps are tangent-space: the
//                          per-pixel vertex normals carry them)
// EXR: albedo.exr, roughness.exr, specular.exr (F0), normals.exr.

#include "photorig/solvers/reflectance/fit.h"

#include "photorig/solvers/camera/camera.h"

#include <opencv2/core.hpp>

#include <string>

namespace photorig::daemon {

inline constexpr double kGltfSpecularColourScale = 25.0;

struct GltfExport {
  std::string gltf_path;
  std::size_t vertices = 0;
  std::size_t triangles = 0;
};

// Writes asset.gltf (+ asset.bin and the textures) into `directory`: a
// vertex per fitted pixel with a finite depth, at the point of its line of
// sight (`rays`, the run's camera) at that height, in mm in the dome's frame;
// through a pinhole the mesh has the object's shape, not the image's. Throws
// std::runtime_error naming the file when one cannot be written.
GltfExport WriteGltfAsset(const std::string& directory, const solvers::reflectance::ReflectanceMaps& maps,
                          const cv::Mat& depth, const solvers::camera::PixelRays& rays);

// The per-pixel glTF parameters of a fit: roughness (CV_32F) and specular
// colour F0 (CV_32FC3), 0 where not fitted.
void GltfParameterMaps(const solvers::reflectance::ReflectanceMaps& maps, cv::Mat* roughness, cv::Mat* f0);

}  // namespace photorig::daemon
