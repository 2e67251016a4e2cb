// Per-pixel fits: each pixel's own lobe, its Lambertian albedo, and its
// albedo under a material's lobe (samples.h).
#include "samples.h"

#include "photorig/solvers/core/progress.h"

#include <algorithm>
#include <cmath>

namespace photorig::solvers::reflectance::internal {

std::vector<PixelLobe> FitPixelLobes(const Samples& s, const std::vector<int>& pixels,
                                     const std::vector<std::uint8_t>& enabled, const core::ProgressCallback& progress) {
  const std::vector<double>& grid = ShapeGrid(brdf::Model::kBlinnPhong);
  std::vector<PixelLobe> out(pixels.size());
  const int count = static_cast<int>(pixels.size());
  core::ProgressThrottle throttle(progress, "per-pixel", count);
  const int block = 256;
  for (int start = 0; start < count; start += block) {
    const int end = std::min(count, start + block);
#pragma omp parallel for schedule(dynamic, 16)
    for (int i = start; i < end; ++i) {
      const int p = pixels[i];
      // No lobe first: a lobe must lower the cost to be kept.
      const PixelSums flat = SumsOf(s, p, {brdf::Model::kLambertian, 0.0}, enabled);
      double best = 0.0;
      PixelLobe result;
      for (int ch = 0; ch < s.channels; ++ch) best += PixelCost(flat.c[ch], 0.0, &result.rho[ch]);
      // A lobe is kept only where it lowers the pixel's BIC by a wide margin
      // (three times the usual penalty, the best of the grid's shapes being
      // picked): otherwise the pixel's noise would pass for a lobe, and
      // materials grouped by these lobes would select that noise.
      const double n = std::max(1, flat.samples * s.channels);
      const double lobe_penalty = 3.0 * (s.channels + 1) * std::log(n);
      double best_bic = n * std::log(std::max(best, 1e-300) / n);
      for (double e : grid) {
        const PixelSums sums = SumsOf(s, p, {brdf::Model::kBlinnPhong, e}, enabled);
        PixelLobe trial;
        trial.exponent = e;
        double cost = 0.0;
        for (int ch = 0; ch < s.channels; ++ch) {
          const ChannelSums& cs = sums.c[ch];
          const double reduced = cs.uu > 0.0 ? cs.hh - cs.uh * cs.uh / cs.uu : 0.0;
          // A lobe the samples barely separate from the diffuse term (reduced
          // coefficient a vanishing part of the lobe's own) has no weight to
          // speak of; and its albedo at normal incidence cannot exceed 1.
          const double w = reduced > 1e-9 * cs.hh && reduced > 0.0
                               ? std::clamp((cs.hy - cs.uh * cs.uy / cs.uu) / reduced, 0.0, 1.0)
                               : 0.0;
          trial.weight[ch] = w;
          cost += PixelCost(cs, w, &trial.rho[ch]);
        }
        const double bic = n * std::log(std::max(cost, 1e-300) / n) + lobe_penalty;
        if (bic < best_bic) {
          best_bic = bic;
          result = trial;
        }
      }
      out[i] = result;
    }
    throttle.Update(end);
  }
  throttle.Finish();
  return out;
}

std::vector<Eigen::Vector3d> FitLambertian(const Samples& s, const std::vector<int>& pixels,
                                           const std::vector<std::uint8_t>& enabled) {
  MaterialFit none;
  return FitAlbedo(s, pixels, none, enabled);
}

std::vector<Eigen::Vector3d> FitAlbedo(const Samples& s, const std::vector<int>& pixels, const MaterialFit& material,
                                       const std::vector<std::uint8_t>& enabled) {
  std::vector<Eigen::Vector3d> rho(pixels.size(), Eigen::Vector3d::Zero());
  const int count = static_cast<int>(pixels.size());
  const Lobe lobe{material.model, material.shape};
#pragma omp parallel for schedule(static)
  for (int i = 0; i < count; ++i) {
    const PixelSums sums = SumsOf(s, pixels[i], lobe, enabled);
    for (int ch = 0; ch < s.channels; ++ch) PixelCost(sums.c[ch], material.specular[ch], &rho[i][ch]);
  }
  return rho;
}

}  // namespace photorig::solvers::reflectance::internal
