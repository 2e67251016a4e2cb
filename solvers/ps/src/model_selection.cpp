#include "model_selection.h"

#include <cmath>
#include <limits>

namespace photorig::ps::internal {
namespace {

double InverseNormalCdf(double p) {
  // Bisection on the CDF: called once per solve, so speed is irrelevant.
  double lo = -10.0, hi = 10.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (0.5 * std::erfc(-mid / std::sqrt(2.0)) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace

std::vector<double> ChiSquareQuantiles(int max_dof, double p) {
  const double z = InverseNormalCdf(p);
  std::vector<double> quantile(max_dof + 1, 0.0);
  for (int dof = 1; dof <= max_dof; ++dof) {
    const double v = dof, t = 1.0 - 2.0 / (9.0 * v) + z * std::sqrt(2.0 / (9.0 * v));
    quantile[dof] = v * t * t * t;
  }
  return quantile;
}


PixelFit LambertianFit(const Eigen::Vector3d& x, double chi2, int used, int rejected) {
  PixelFit fit;
  fit.ok = x.norm() > 0.0;
  fit.normal = x.normalized();
  fit.albedo = M_PI * x.norm();
  fit.chi2 = chi2;
  fit.used = used;
  fit.rejected = rejected;
  return fit;
}

ModelLadder::ModelLadder(Method method, const ModelSelectionOptions& options, int lights)
    : method_(method),
      quantile_(ChiSquareQuantiles(lights, options.adequacy_quantile)),
      gross_u2_(options.gross_outlier_sigma * options.gross_outlier_sigma),
      max_rejected_fraction_(options.max_rejected_fraction) {}

LadderStep ModelLadder::Next(const LadderFits& fits) const {
  using Action = LadderStep::Action;
  const PixelFit& lambertian = fits.lambertian;
  switch (method_) {
    case Method::kL2:
    case Method::kLambertian: return Keep(lambertian);
    case Method::kRobust:
      if (!fits.robust) return {Action::kReweight};
      return Keep(*fits.robust);
    case Method::kBlinnPhong:
      if (!fits.robust) return {Action::kTrim};
      if (!fits.lobe) return {Action::kFitLobe, nullptr, fits.robust->ok ? &*fits.robust : &lambertian};
      return Keep(fits.lobe->blinn_phong);
    case Method::kAuto: break;
  }
  // A richer model is fitted only where the samples can tell it apart: with
  // no sample to spare nothing can be tested or trimmed.
  if (Adequate(lambertian) || !(lambertian.Dof() > 0)) return Keep(lambertian);
  if (!fits.lit) return {Action::kRefitLit};
  if (Adequate(*fits.lit)) return Keep(*fits.lit);
  if (!fits.robust) return {Action::kTrim};
  if (Adequate(*fits.robust)) return Keep(*fits.robust);  // it trimmed at most its allowance
  if (lambertian.used <= kBlinnPhongParameters) return Keep(lambertian);
  if (!fits.lobe) return {Action::kFitLobe, nullptr, fits.robust->ok ? &*fits.robust : &lambertian};
  // Neither simple model is adequate: the information criterion decides
  // between the models fitted to all usable samples.
  const LadderFits::Lobe& lobe = *fits.lobe;
  return Keep(lobe.blinn_phong.ok && lobe.blinn_phong.Bic() < lobe.lambertian.Bic() ? lobe.blinn_phong
                                                                                     : lobe.lambertian);
}

std::vector<float> ModelLadder::ScreenThresholds() const {
  const int lights = static_cast<int>(quantile_.size()) - 1;
  std::vector<float> threshold(lights + 1, std::numeric_limits<float>::infinity());
  if (method_ == Method::kAuto)
    for (int dof = 1; dof + 3 <= lights; ++dof) threshold[dof + 3] = static_cast<float>(dof / quantile_[dof]);
  return threshold;
}

}  // namespace photorig::ps::internal
