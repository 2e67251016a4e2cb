#pragma once
// The specular lobes of models.h, templated so that the fitter differentiates
// them with Ceres' jets. `specular` is one channel's k_s (Blinn-Phong) or F0
// (GGX); `shape` the exponent or the roughness.

#include "photorig/solvers/brdf/models.h"

#include <cmath>

namespace photorig::solvers::brdf::internal {

template <typename T>
T BlinnPhongLobe(const T& specular, const T& exponent, const Geometry& g) {
  using std::exp;
  using std::log;
  const T normalisation = (exponent + 2.0) * (exponent + 4.0) / (8.0 * M_PI * (exp(-0.5 * M_LN2 * exponent) + exponent));
  // cos^e as exp(e log cos): cos_h > 0 whenever both directions are above the horizon.
  return specular * normalisation * exp(exponent * log(g.cos_h));
}

template <typename T>
T GgxLobe(const T& f0, const T& roughness, const Geometry& g) {
  using std::sqrt;
  const T a2 = roughness * roughness;
  const T t = g.cos_h * g.cos_h * (a2 - 1.0) + 1.0;
  const T d = a2 / (M_PI * t * t);
  const T g_i = 2.0 * g.cos_i / (g.cos_i + sqrt(a2 + (1.0 - a2) * g.cos_i * g.cos_i));
  const T g_o = 2.0 * g.cos_o / (g.cos_o + sqrt(a2 + (1.0 - a2) * g.cos_o * g.cos_o));
  const double m = 1.0 - g.cos_d, m5 = m * m * m * m * m;
  const T fresnel = f0 + (1.0 - f0) * m5;
  return d * g_i * g_o * fresnel / (4.0 * g.cos_i * g.cos_o);
}

template <typename T>
T Lobe(Model model, const T& specular, const T& shape, const Geometry& g) {
  switch (model) {
    case Model::kBlinnPhong: return BlinnPhongLobe(specular, shape, g);
    case Model::kGgx: return GgxLobe(specular, shape, g);
    case Model::kLambertian: break;
  }
  return T(0.0);
}

}  // namespace photorig::solvers::brdf::internal
