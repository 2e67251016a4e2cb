#include "photorig/solvers/reflectance/gltf_material.h"

#include "samples.h"

#include <algorithm>
#include <cmath>

namespace photorig::solvers::reflectance {

GltfMaterial ToGltf(const MaterialFit& material) {
  GltfMaterial out;
  switch (material.model) {
    case brdf::Model::kLambertian: break;
    case brdf::Model::kGgx:
    // Near the peak Beckmann's m and Ward's alpha play GGX's alpha (the
    // spatially varying fit refuses both lobes; the switch stays whole).
    case brdf::Model::kWard:
    case brdf::Model::kCookTorrance:
      out.roughness = std::sqrt(material.shape);
      out.specular_colour = material.specular / 0.04;
      break;
    case brdf::Model::kBlinnPhong:
    case brdf::Model::kTwoBlinnPhong:  // refused by the spatially varying fit; its first lobe would map so
      out.roughness = std::sqrt(std::sqrt(2.0 / (material.shape + 2.0)));
      out.specular_colour = material.specular / 0.04;
      break;
  }
  out.roughness = std::clamp(out.roughness, 0.0, 1.0);
  return out;
}

double GltfBaseColour(double rho, const GltfMaterial& material, int channel) {
  const double f0 = std::min(0.04 * material.specular_colour[channel], 0.99);
  return std::clamp(rho / (1.0 - f0), 0.0, 1.0);
}

Eigen::Vector3d EvaluateGltf(const Eigen::Vector3d& base_colour, const GltfMaterial& m, const Eigen::Vector3d& wi,
                             const Eigen::Vector3d& wo) {
  if (wi.z() <= 0.0 || wo.z() <= 0.0) return Eigen::Vector3d::Zero();
  const Eigen::Vector3d h = (wi + wo).normalized();
  const double alpha = m.roughness * m.roughness, a2 = std::max(alpha * alpha, 1e-12);
  const double t = h.z() * h.z() * (a2 - 1.0) + 1.0;
  const double d = a2 / (M_PI * t * t);
  const double v = 1.0 / ((wi.z() + std::sqrt(a2 + (1.0 - a2) * wi.z() * wi.z())) *
                          (wo.z() + std::sqrt(a2 + (1.0 - a2) * wo.z() * wo.z())));
  const double m5 = std::pow(1.0 - std::abs(wo.dot(h)), 5.0);
  Eigen::Vector3d f;
  for (int c = 0; c < 3; ++c) {
    const double f0 = std::min(0.04 * m.specular_colour[c], 1.0);
    const double fresnel = f0 + (1.0 - f0) * m5;
    // With no specular colour the material is purely diffuse (KHR_materials_specular with specularFactor 0).
    f[c] = (m.specular_colour[c] > 0.0 ? (1.0 - fresnel) : 1.0) * base_colour[c] / M_PI +
           (m.specular_colour[c] > 0.0 ? fresnel * d * v : 0.0);
  }
  return f;
}

double GltfMappingError(const MaterialFit& material, const std::vector<Eigen::Vector3d>& lights,
                        const Eigen::Vector3d& view_direction) {
  const GltfMaterial gltf = ToGltf(material);
  const Eigen::Vector3d rho = Eigen::Vector3d::Constant(0.5);
  Eigen::Vector3d base;
  for (int c = 0; c < 3; ++c) base[c] = GltfBaseColour(rho[c], gltf, c);
  const brdf::ModelParams params{material.model, rho, material.specular, material.shape};
  double diff = 0.0, norm = 0.0;
  // Normals on a grid over the hemisphere facing the view.
  for (int i = 0; i < 21; ++i)
    for (int j = 0; j < 21; ++j) {
      const double x = -0.95 + 0.095 * i, y = -0.95 + 0.095 * j;
      if (x * x + y * y >= 0.95) continue;
      const Eigen::Vector3d n(x, y, std::sqrt(1.0 - x * x - y * y));
      const Eigen::Vector3d wo = internal::ToLocal(n, view_direction.normalized());
      for (const Eigen::Vector3d& l : lights) {
        const Eigen::Vector3d wi = internal::ToLocal(n, l.normalized());
        if (wi.z() <= 0.0) continue;
        const Eigen::Vector3d a = brdf::Evaluate(params, wi, wo) * wi.z(), b = EvaluateGltf(base, gltf, wi, wo) * wi.z();
        diff += (a - b).squaredNorm();
        norm += a.squaredNorm();
      }
    }
  return norm > 0.0 ? std::sqrt(diff / norm) : 0.0;
}

}  // namespace photorig::solvers::reflectance
