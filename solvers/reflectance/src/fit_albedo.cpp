// The reflectance fit's per-material stage: with the materials and their
// lobes chosen, each pixel's albedo, its deviation and residual under its
// material, and the pixels that material does not explain.
#include "fit_stages.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace photorig::solvers::reflectance::internal {
namespace {

// Writes the pixels of material m (`group`), sets fit->rms_residual and
// flags the group's poor fits: residuals far above the material's typical one.
void FitGroupPixels(const ReflectanceOptions& options, const Samples& s, int m, const std::vector<int>& group,
                    MaterialFit* fit, cv::Mat* flags, ReflectanceMaps* maps, FittedPixels* fitted,
                    ReflectanceSummary* summary) {
  std::vector<PixelSums> sums;
  FitGroup(s, group, {fit->model, fit->shape}, {}, &sums);
  std::vector<double> rms(group.size());
  double squared_sum = 0.0;
  long long count = 0;
  for (std::size_t i = 0; i < group.size(); ++i) {
    const int p = group[i];
    fitted->material_of[p] = m;
    const PixelResidual residual = WritePixel(s, p, m, sums[i], *fit, maps, fitted);
    rms[i] = residual.rms;
    squared_sum += residual.squared_sum;
    count += residual.count;
    fitted->chi_square += residual.chi_square;
    fitted->residuals += residual.count;
  }
  fit->rms_residual = std::sqrt(squared_sum / std::max<long long>(1, count));
  const double typical = Median(rms);
  fitted->typical_rms[m] = typical;
  for (std::size_t i = 0; i < group.size(); ++i)
    if (rms[i] > options.poor_fit_ratio * typical && rms[i] > 0.0) {
      const int p = group[i];
      flags->at<std::uint8_t>(s.pixel_index[p] / s.width, s.pixel_index[p] % s.width) =
          static_cast<std::uint8_t>(PixelFlag::kPoorFit);
      ++summary->pixels_poor_fit;
    }
}

}  // namespace

PixelResidual ResidualOf(const Samples& s, int p, const PixelSums& sums, const MaterialFit& fit, double* rho) {
  const int C = s.channels;
  PixelResidual out;
  for (int ch = 0; ch < C; ++ch) out.chi_square += PixelCost(sums.c[ch], fit.specular[ch], &rho[ch]);
  for (int j = 0; j < s.lights; ++j) {
    const std::size_t cell = s.At(p, j);
    if (!s.usable[cell]) continue;
    for (int ch = 0; ch < C; ++ch) {
      const double d = s.value[cell * C + ch] -
                       Predict(s, cell, {fit.model, fit.shape}, fit.specular[ch], rho[ch], s.Irradiance(cell, j, ch));
      out.squared_sum += d * d;
      ++out.count;
    }
  }
  out.rms = std::sqrt(out.squared_sum / std::max<long long>(1, out.count));
  return out;
}

PixelResidual WritePixel(const Samples& s, int p, int m, const PixelSums& sums, const MaterialFit& fit,
                         ReflectanceMaps* maps, FittedPixels* fitted) {
  const int C = s.channels;
  const int r = s.pixel_index[p] / s.width, c = s.pixel_index[p] % s.width;
  float* albedo = maps->albedo.ptr<float>(r) + c * C;
  float* sigma = maps->albedo_sigma.ptr<float>(r) + c * C;
  double rho[3] = {0.0, 0.0, 0.0};
  const PixelResidual out = ResidualOf(s, p, sums, fit, rho);
  for (int ch = 0; ch < C; ++ch) {
    albedo[ch] = static_cast<float>(rho[ch]);
    // Weighted least squares, scaled by the pixel's own chi^2 per dof (one dof per channel used by rho).
    double unused;
    const double channel_cost = PixelCost(sums.c[ch], fit.specular[ch], &unused);
    const double dof = std::max(1, sums.samples - 1);
    sigma[ch] = static_cast<float>(std::sqrt(channel_cost / dof / std::max(sums.c[ch].uu, 1e-300)));
  }
  fitted->rms[p] = out.rms;
  maps->rms_residual.at<float>(r, c) = static_cast<float>(out.rms);
  maps->material.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(m);
  return out;
}

FittedPixels FitMaterialPixels(const ReflectanceOptions& options, const Samples& s, const cv::Mat& normals,
                               const PixelClasses& classes, const Partition& best, cv::Mat* flags,
                               ReflectanceMaps* maps, ReflectanceSummary* summary) {
  const int C = s.channels;
  maps->albedo = cv::Mat(s.height, s.width, CV_32FC(C), cv::Scalar::all(std::numeric_limits<float>::quiet_NaN()));
  maps->albedo_sigma = maps->albedo.clone();
  maps->material = cv::Mat(s.height, s.width, CV_8U, cv::Scalar(255));
  maps->rms_residual = cv::Mat(s.height, s.width, CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  maps->normals = normals.clone();
  maps->materials.clear();
  core::ProgressThrottle albedo_progress(options.progress, "albedo", static_cast<std::int64_t>(best.groups.size()));
  FittedPixels fitted;
  fitted.material_of.assign(s.pixels, -1);
  fitted.rms.assign(s.pixels, 0.0);
  fitted.typical_rms.assign(best.groups.size(), 0.0);
  for (std::size_t m = 0; m < best.groups.size(); ++m) {
    MaterialFit fit = best.materials[m].fit;
    FitGroupPixels(options, s, static_cast<int>(m), best.groups[m], &fit, flags, maps, &fitted, summary);
    DescribeLighting(options, s, best.groups[m], classes, &fit);
    for (Warning w : fit.warnings) AddWarning(&summary->warnings, w);
    maps->materials.push_back(fit);
    albedo_progress.Update(static_cast<std::int64_t>(m + 1));
  }
  albedo_progress.Finish();
  return fitted;
}

}  // namespace photorig::solvers::reflectance::internal
