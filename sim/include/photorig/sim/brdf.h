#pragma once
// Reflectance models behind one interface, evaluated per pixel.
// Conventions: every direction is a unit vector pointing away from the surface
// (w_i towards the light, w_o towards the camera), n is the unit normal, and
// f_r is in 1/sr. Radiance leaving a point lit by irradiance E (normal
// incidence) from w_i is L = f_r(w_i, w_o) * E * max(0, n.w_i).
//
//   lambertian   f = rho_d / pi
//   blinn_phong  f = rho_d / pi + rho_s (e + 2) / (2 pi) (n.h)^e,   h = normalize(w_i + w_o)
//   ggx          f = rho_d / pi * (1 - F(n.w_i)) (1 - F(n.w_o)) / (1 - F0)
//                  + D(h) G1(w_i) G1(w_o) F(w_i.h) / (4 (n.w_i)(n.w_o))
//                D(h)  = a^2 / (pi ((n.h)^2 (a^2 - 1) + 1)^2)            a = roughness
//                G1(v) = 2 (n.v) / ((n.v) + sqrt(a^2 + (1 - a^2)(n.v)^2))  (separable Smith)
//                F(c)  = F0 + (1 - F0)(1 - c)^5                            (Schlick)
//   cook_torrance f = rho_d / pi + k_s D G F(w_i.h) / (pi (n.w_i)(n.w_o))   k_s = rho_s, m = shininess
//                Ngan et al. 2005's form (Beckmann D, V-groove G, Schlick F with F0),
//                evaluated by solvers/brdf (models.h), so the fit and the simulator agree
//   mirror       delta lobe about 2 (n.w_o) n - w_o with reflectance rho_s
//   tabulated    a measured table (MERL .binary or EPFL RGL .bsdf) as
//                solvers/brdf evaluates it: trilinear between MERL's cells, RGL's
//                own interpolation; one channel of it, or their mean for a grey camera
// docs/simulation.md discusses energy conservation of each model.

#include "photorig/solvers/brdf/measured.h"

#include <Eigen/Core>

#include <memory>
#include <string>
#include <vector>

namespace photorig::sim {

// The per-pixel parameters every model reads (unused ones are ignored), so
// parameter maps can be written beside the frames as ground truth.
struct BrdfParams {
  float rho_d = 0.5f;      // diffuse albedo
  float rho_s = 0.0f;      // specular weight (blinn_phong, cook_torrance k_s), mirror reflectance (mirror)
  float shininess = 0.0f;  // Blinn-Phong exponent e, GGX roughness a, or Cook-Torrance's Beckmann m
  float f0 = 0.04f;        // GGX and Cook-Torrance Fresnel reflectance at normal incidence
};

class Brdf {
 public:
  enum class Model { kLambertian, kBlinnPhong, kGgx, kCookTorrance, kMirror, kTabulated };

  virtual ~Brdf() = default;
  virtual Model model() const = 0;
  // f_r for a non-delta model; 0 for a delta model.
  virtual double Eval(const Eigen::Vector3d& n, const Eigen::Vector3d& wi, const Eigen::Vector3d& wo,
                      const BrdfParams& p) const = 0;
  // Delta models reflect the radiance seen along MirrorDirection(n, w_o),
  // scaled by this reflectance; others return 0.
  virtual bool IsDelta() const { return false; }
  virtual double DeltaReflectance(const BrdfParams&) const { return 0.0; }

  static Model ParseModel(const std::string& name);  // throws std::invalid_argument
  static const char* ModelName(Model model);
};

// 2 (n.w_o) n - w_o.
Eigen::Vector3d MirrorDirection(const Eigen::Vector3d& n, const Eigen::Vector3d& wo);

// `table` is needed by (and only by) kTabulated.
// `table`: the tabulated model's measured BRDF (required for it, ignored by the
// others); `channel`: which of its channels (0 R, 1 G, 2 B) a colour camera's
// channel sees, or -1 for the mean of the three (a grey camera).
std::unique_ptr<Brdf> MakeBrdf(Brdf::Model model, std::shared_ptr<const solvers::brdf::MeasuredBrdf> table = nullptr,
                               int channel = -1);

}  // namespace photorig::sim
