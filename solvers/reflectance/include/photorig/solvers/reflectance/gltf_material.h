#pragma once
// The fitted lobes in glTF 2.0's metallic-roughness model, and that model's
// BRDF (glTF 2.0 specification, appendix B, with KHR_materials_specular), so
// that the error of the mapping can be measured:
//
//   f = (1 - F) base / pi + F D V,       metallic = 0 (every fitted material is a dielectric)
//   F = F0 + (1 - F0)(1 - |v.h|)^5,      F0 = min(0.04 specular_colour, 1)   (KHR_materials_specular)
//   D = alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2),   alpha = roughness^2
//   V = 1 / ((n.l + sqrt(alpha^2 + (1 - alpha^2)(n.l)^2)) (n.v + sqrt(alpha^2 + (1 - alpha^2)(n.v)^2)))
//
// Mapping (docs/reflectance.md):
//   no lobe        roughness 1, specular colour 0
//   GGX (a, F0)    roughness = sqrt(a), specular colour = F0 / 0.04
//   Blinn-Phong    alpha = sqrt(2 / (e + 2)) (Walter et al.'s equal-width rule),
//   (e, k_s)       roughness = sqrt(alpha), specular colour = k_s / 0.04 (the lobe's albedo at normal incidence)
// base colour = rho_d / (1 - F0): glTF's diffuse is attenuated by (1 - F), the
// fitted models' is not, so the base colour makes up the part F0 takes at
// normal incidence.

#include "photorig/solvers/reflectance/fit.h"

#include <Eigen/Core>

namespace photorig::solvers::reflectance {

struct GltfMaterial {
  double roughness = 1.0;
  Eigen::Vector3d specular_colour = Eigen::Vector3d::Zero();  // KHR_materials_specular specularColorFactor
};

GltfMaterial ToGltf(const MaterialFit& material);
// The base colour that gives albedo `rho` (one channel) under `material`'s F0.
double GltfBaseColour(double rho, const GltfMaterial& material, int channel);

// glTF's BRDF in 1/sr per channel for directions in the surface frame (normal = z).
Eigen::Vector3d EvaluateGltf(const Eigen::Vector3d& base_colour, const GltfMaterial& material, const Eigen::Vector3d& wi,
                             const Eigen::Vector3d& wo);

// Relative RMS difference between the fitted model and its glTF form,
// rendered under `lights` at normals spread over the hemisphere facing the
// view (albedo 0.5): sqrt(sum (glTF - fitted)^2 / sum fitted^2).
double GltfMappingError(const MaterialFit& material, const std::vector<Eigen::Vector3d>& lights,
                        const Eigen::Vector3d& view_direction);

}  // namespace photorig::solvers::reflectance
