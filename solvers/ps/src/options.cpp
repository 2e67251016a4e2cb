// The options of SolvePhotometricStereo: method names and validation.
#include "photorig/solvers/ps/photometric_stereo.h"

#include <cmath>

namespace photorig::solvers::ps {

void UseDerivative(BlinnPhongDerivative derivative, BlinnPhongOptions* options) {
  using autodiff::DerivativeMethod;
  options->fitter = derivative == BlinnPhongDerivative::kLanes ? BlinnPhongOptions::Fitter::kLanes
                                                                : BlinnPhongOptions::Fitter::kPerPixel;
  switch (derivative) {
    case BlinnPhongDerivative::kLanes: break;
    case BlinnPhongDerivative::kForward: options->derivative = DerivativeMethod::kForward; break;
    case BlinnPhongDerivative::kReverse: options->derivative = DerivativeMethod::kReverse; break;
    case BlinnPhongDerivative::kSymbolic: options->derivative = DerivativeMethod::kSymbolic; break;
    case BlinnPhongDerivative::kCentralDifference: options->derivative = DerivativeMethod::kCentralDifference; break;
  }
}

bool RobustOptions::IsValid(std::string* why) const {
  if (warmup_iterations < 0 || max_iterations < 1) return core::Refuse(why, "robust: iterations must be >= 0 (warm-up) and >= 1");
  if (!(relative_tolerance > 0.0)) return core::Refuse(why, "robust: relative_tolerance must be > 0");
  if (!(inlier_weight > 0.0 && inlier_weight < 1.0)) return core::Refuse(why, "robust: inlier_weight must be in (0, 1)");
  return true;
}

bool BlinnPhongOptions::IsValid(std::string* why) const {
  if (max_iterations < 1) return core::Refuse(why, "blinn_phong: max_iterations must be >= 1");
  if (!(relative_tolerance > 0.0 && relative_tolerance < 1.0)) return core::Refuse(why, "blinn_phong: relative_tolerance must be in (0, 1)");
  if (!(min_exponent > 0.0 && min_exponent < max_exponent)) return core::Refuse(why, "blinn_phong: need 0 < min_exponent < max_exponent");
  return true;
}

bool ModelSelectionOptions::IsValid(std::string* why) const {
  if (!(adequacy_quantile > 0.5 && adequacy_quantile < 1.0)) return core::Refuse(why, "selection: adequacy_quantile must be in (0.5, 1)");
  if (!(lambertian_quantile > 0.5 && lambertian_quantile <= adequacy_quantile))
    return core::Refuse(why, "selection: lambertian_quantile must be in (0.5, adequacy_quantile]");
  if (!(max_rejected_fraction >= 0.0 && max_rejected_fraction < 1.0))
    return core::Refuse(why, "selection: max_rejected_fraction must be in [0, 1)");
  if (!(gross_outlier_sigma > 0.0) || !std::isfinite(gross_outlier_sigma))
    return core::Refuse(why, "selection: gross_outlier_sigma must be finite and > 0");
  if (!(glossy_region_fraction > 0.0 && glossy_region_fraction <= 1.0))
    return core::Refuse(why, "selection: glossy_region_fraction must be in (0, 1]");
  if (!(spike_fraction >= 0.0 && spike_fraction < 0.5))
    return core::Refuse(why, "selection: spike_fraction must be in [0, 0.5)");
  return true;
}

bool PhotometricStereoOptions::IsValid(std::string* why) const {
  if (!(shadow_threshold_read_sigmas >= 0.0) || !std::isfinite(shadow_threshold_read_sigmas)) {
    if (why) *why = "shadow_threshold_read_sigmas must be finite and >= 0";
    return false;
  }
  if (!(min_signal_read_sigmas >= 0.0) || !std::isfinite(min_signal_read_sigmas) || min_signal_pixels < 1) {
    if (why) *why = "min_signal_read_sigmas must be finite and >= 0, min_signal_pixels >= 1";
    return false;
  }
  return lambertian.IsValid(why) && robust.IsValid(why) && blinn_phong.IsValid(why) && selection.IsValid(why);
}

}  // namespace photorig::solvers::ps
