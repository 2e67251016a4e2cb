// The types of fit.h: the noise model, the stack's and the options' checks,
// the names of flags and warnings. FitReflectance is fit_reflectance.cpp.
#include "photorig/solvers/reflectance/fit.h"

#include "photorig/solvers/core/names.h"

#include <cmath>
#include <string>

namespace photorig::solvers::reflectance {

double SensorNoise::Variance(int channel, double signal) const {
  const double positive = std::max(signal, 0.0);
  return read_sigma[channel] * read_sigma[channel] + shot_gain[channel] * positive +
         relative[channel] * relative[channel] * positive * positive;
}

Eigen::Vector3d ReflectanceStack::Intensity(int light) const {
  return light_intensities.empty() ? Eigen::Vector3d::Ones() : light_intensities[light];
}

bool ReflectanceStack::IsValid(std::string* why) const {
  if (images.size() < 3) return core::Refuse(why, "the stack needs at least 3 images, has " + std::to_string(images.size()));
  if (light_directions.size() != images.size())
    return core::Refuse(why, std::to_string(images.size()) + " images but " + std::to_string(light_directions.size()) +
                             " light directions");
  if (!light_intensities.empty() && light_intensities.size() != images.size())
    return core::Refuse(why, std::to_string(images.size()) + " images but " + std::to_string(light_intensities.size()) +
                             " light intensities");
  for (std::size_t j = 0; j < images.size(); ++j) {
    const cv::Mat& m = images[j];
    if (m.type() != CV_32FC1 && m.type() != CV_32FC3)
      return core::Refuse(why, "image " + std::to_string(j) + " is not CV_32FC1 or CV_32FC3");
    if (m.size() != images.front().size() || m.type() != images.front().type())
      return core::Refuse(why, "image " + std::to_string(j) + " differs in size or channels from image 0");
    if (!m.isContinuous()) return core::Refuse(why, "image " + std::to_string(j) + " is not continuous");
    if (std::abs(light_directions[j].norm() - 1.0) > 1e-3)
      return core::Refuse(why, "light direction " + std::to_string(j) + " is not a unit vector");
    if (!light_intensities.empty() && !(light_intensities[j].minCoeff() > 0.0))
      return core::Refuse(why, "light intensity " + std::to_string(j) + " is not positive");
  }
  if (std::abs(view_direction.norm() - 1.0) > 1e-3) return core::Refuse(why, "the view direction is not a unit vector");
  if (!near_lights.empty() && near_lights.size() != images.size())
    return core::Refuse(why, std::to_string(images.size()) + " images but " + std::to_string(near_lights.size()) +
                             " near LEDs");
  if (!near_lights.empty() && (points_mm.type() != CV_32FC3 || points_mm.size() != images.front().size()))
    return core::Refuse(why, "near LEDs need points_mm: CV_32FC3 of the images' size");
  if (!views.empty() && (views.type() != CV_32FC3 || views.size() != images.front().size()))
    return core::Refuse(why, "views must be CV_32FC3 of the images' size");
  if (!(noise.read_sigma.minCoeff() >= 0.0 && noise.shot_gain.minCoeff() >= 0.0 && noise.relative.minCoeff() >= 0.0) ||
      !noise.read_sigma.allFinite() || !noise.shot_gain.allFinite() || !noise.relative.allFinite())
    return core::Refuse(why, "the noise model's terms must be finite and >= 0");
  return true;
}

namespace {

constexpr core::NameTable<PixelFlag, 6> kPixelFlagNames = {{
    {PixelFlag::kFitted, "fitted"}, {PixelFlag::kOutsideMask, "outside-mask"}, {PixelFlag::kNoNormal, "no-normal"},
    {PixelFlag::kTooFewSamples, "too-few-samples"}, {PixelFlag::kPoorFit, "poor-fit"}, {PixelFlag::kMixed, "mixed"},
}};

constexpr core::NameTable<Warning, 4> kWarningNames = {{
    {Warning::kTooFewHighlightLights, "too-few-highlight-lights"}, {Warning::kHighlightsUnobserved, "highlights-unobserved"},
    {Warning::kSaturatedHighlights, "saturated-highlights"}, {Warning::kInconsistentIntensities, "inconsistent-intensities"},
}};

}  // namespace

const char* PixelFlagName(PixelFlag flag) { return core::NameOf(kPixelFlagNames, flag); }

const char* WarningName(Warning warning) { return core::NameOf(kWarningNames, warning); }

bool ReflectanceOptions::IsValid(std::string* why) const {
  if (max_materials < 1 || max_materials > 16) return core::Refuse(why, "max_materials must be in [1, 16]");
  for (brdf::Model m : lobes) {
    if (m == brdf::Model::kLambertian) return core::Refuse(why, "lobes lists specular lobes only (no lobe is always a candidate)");
    if (m != brdf::Model::kBlinnPhong && m != brdf::Model::kGgx)
      return core::Refuse(why, std::string("lobes may hold blinn_phong and ggx; ") + brdf::ModelName(m) +
                               " is fitted to whole tables (photorig brdf fit), not per material");
  }
  if (!(min_cosine >= 0.0 && min_cosine < 1.0)) return core::Refuse(why, "min_cosine must be in [0, 1)");
  if (min_samples < 3) return core::Refuse(why, "min_samples must be at least 3");
  if (!(poor_fit_ratio > 1.0)) return core::Refuse(why, "poor_fit_ratio must exceed 1");
  if (!(mixed_pixel_alpha >= 0.0 && mixed_pixel_alpha < 1.0)) return core::Refuse(why, "mixed_pixel_alpha must be in [0, 1)");
  if (!(split_alpha > 0.0 && split_alpha < 0.5)) return core::Refuse(why, "split_alpha must be in (0, 0.5)");
  if (shape_search_pixels < 10) return core::Refuse(why, "shape_search_pixels must be at least 10");
  if (kmeans_restarts < 1) return core::Refuse(why, "kmeans_restarts must be at least 1");
  if (min_highlight_lights < 1) return core::Refuse(why, "min_highlight_lights must be at least 1");
  if (!(unobserved_half_angle_deg > 0.0 && unobserved_half_angle_deg < 90.0))
    return core::Refuse(why, "unobserved_half_angle_deg must be in (0, 90)");
  if (!(max_saturated_fraction >= 0.0 && max_saturated_fraction <= 1.0))
    return core::Refuse(why, "max_saturated_fraction must be in [0, 1]");
  if (!(max_intensity_error > 0.0)) return core::Refuse(why, "max_intensity_error must be positive");
  return true;
}

}  // namespace photorig::solvers::reflectance
