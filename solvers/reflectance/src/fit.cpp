// FitReflectance and its options' and inputs' checks; the fit's stages are
// in the files fit_stages.h lists.
#include "photorig/solvers/reflectance/fit.h"

#include "fit_stages.h"

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
  auto fail = [&](std::string text) {
    if (why) *why = std::move(text);
    return false;
  };
  if (images.size() < 3) return fail("the stack needs at least 3 images, has " + std::to_string(images.size()));
  if (light_directions.size() != images.size())
    return fail(std::to_string(images.size()) + " images but " + std::to_string(light_directions.size()) +
                " light directions");
  if (!light_intensities.empty() && light_intensities.size() != images.size())
    return fail(std::to_string(images.size()) + " images but " + std::to_string(light_intensities.size()) +
                " light intensities");
  for (std::size_t j = 0; j < images.size(); ++j) {
    const cv::Mat& m = images[j];
    if (m.type() != CV_32FC1 && m.type() != CV_32FC3)
      return fail("image " + std::to_string(j) + " is not CV_32FC1 or CV_32FC3");
    if (m.size() != images.front().size() || m.type() != images.front().type())
      return fail("image " + std::to_string(j) + " differs in size or channels from image 0");
    if (!m.isContinuous()) return fail("image " + std::to_string(j) + " is not continuous");
    if (std::abs(light_directions[j].norm() - 1.0) > 1e-3)
      return fail("light direction " + std::to_string(j) + " is not a unit vector");
    if (!light_intensities.empty() && !(light_intensities[j].minCoeff() > 0.0))
      return fail("light intensity " + std::to_string(j) + " is not positive");
  }
  if (std::abs(view_direction.norm() - 1.0) > 1e-3) return fail("the view direction is not a unit vector");
  if (!(noise.read_sigma.minCoeff() >= 0.0 && noise.shot_gain.minCoeff() >= 0.0 && noise.relative.minCoeff() >= 0.0) ||
      !noise.read_sigma.allFinite() || !noise.shot_gain.allFinite() || !noise.relative.allFinite())
    return fail("the noise model's terms must be finite and >= 0");
  return true;
}

const char* PixelFlagName(PixelFlag flag) {
  switch (flag) {
    case PixelFlag::kFitted: return "fitted";
    case PixelFlag::kOutsideMask: return "outside-mask";
    case PixelFlag::kNoNormal: return "no-normal";
    case PixelFlag::kTooFewSamples: return "too-few-samples";
    case PixelFlag::kPoorFit: return "poor-fit";
    case PixelFlag::kMixed: return "mixed";
  }
  return "?";
}

const char* WarningName(Warning warning) {
  switch (warning) {
    case Warning::kTooFewHighlightLights: return "too-few-highlight-lights";
    case Warning::kHighlightsUnobserved: return "highlights-unobserved";
    case Warning::kSaturatedHighlights: return "saturated-highlights";
    case Warning::kInconsistentIntensities: return "inconsistent-intensities";
  }
  return "?";
}

bool ReflectanceOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& text) {
    if (why) *why = text;
    return false;
  };
  if (max_materials < 1 || max_materials > 16) return fail("max_materials must be in [1, 16]");
  for (brdf::Model m : lobes) {
    if (m == brdf::Model::kLambertian) return fail("lobes lists specular lobes only (no lobe is always a candidate)");
    if (m != brdf::Model::kBlinnPhong && m != brdf::Model::kGgx)
      return fail(std::string("lobes may hold blinn_phong and ggx; ") + brdf::ModelName(m) +
                  " is fitted to whole tables (photorig brdf fit), not per material");
  }
  if (!(min_cosine >= 0.0 && min_cosine < 1.0)) return fail("min_cosine must be in [0, 1)");
  if (min_samples < 3) return fail("min_samples must be at least 3");
  if (!(poor_fit_ratio > 1.0)) return fail("poor_fit_ratio must exceed 1");
  if (!(mixed_pixel_alpha >= 0.0 && mixed_pixel_alpha < 1.0)) return fail("mixed_pixel_alpha must be in [0, 1)");
  if (!(split_alpha > 0.0 && split_alpha < 0.5)) return fail("split_alpha must be in (0, 0.5)");
  if (shape_search_pixels < 10) return fail("shape_search_pixels must be at least 10");
  if (kmeans_restarts < 1) return fail("kmeans_restarts must be at least 1");
  if (min_highlight_lights < 1) return fail("min_highlight_lights must be at least 1");
  if (!(unobserved_half_angle_deg > 0.0 && unobserved_half_angle_deg < 90.0))
    return fail("unobserved_half_angle_deg must be in (0, 90)");
  if (!(max_saturated_fraction >= 0.0 && max_saturated_fraction <= 1.0))
    return fail("max_saturated_fraction must be in [0, 1]");
  if (!(max_intensity_error > 0.0)) return fail("max_intensity_error must be positive");
  return true;
}

namespace {

// Ends *summary and returns false when the options or the inputs cannot be fitted.
bool CheckInputs(const ReflectanceOptions& options, const ReflectanceStack& stack, const cv::Mat& normals,
                 const cv::Mat& mask, const ReflectanceMaps* maps, ReflectanceSummary* summary) {
  std::string why;
  if (!options.IsValid(&why)) {
    summary->End(core::Termination::kInvalidOptions, why);
    return false;
  }
  if (!stack.IsValid(&why)) {
    summary->End(core::Termination::kInvalidInput, why);
    return false;
  }
  if (normals.type() != CV_32FC3 || normals.size() != stack.images.front().size()) {
    summary->End(core::Termination::kInvalidInput, "normals must be CV_32FC3 of the stack's size");
    return false;
  }
  if (!mask.empty() && (mask.type() != CV_8U || mask.size() != normals.size())) {
    summary->End(core::Termination::kInvalidInput, "mask must be CV_8U of the stack's size");
    return false;
  }
  if (maps == nullptr) {
    summary->End(core::Termination::kInvalidInput, "no output maps given");
    return false;
  }
  return true;
}

// The pixels fitted, the chi-square per residual, the materials and the
// message listing the warnings, once every stage has run.
void Conclude(const std::vector<int>& active, const internal::FittedPixels& fitted, const ReflectanceMaps& maps,
              ReflectanceSummary* summary) {
  summary->reduced_chi_square =
      fitted.residuals > 0 ? fitted.chi_square / static_cast<double>(fitted.residuals) : 0.0;
  summary->materials = static_cast<int>(maps.materials.size());
  summary->pixels_fitted = static_cast<int>(active.size()) - summary->pixels_poor_fit - summary->pixels_mixed;
  summary->termination = core::Termination::kSuccess;
  if (!summary->warnings.empty()) {
    summary->message = "warnings:";
    for (Warning w : summary->warnings) summary->message += std::string(" ") + WarningName(w);
  }
}

}  // namespace

ReflectanceSummary FitReflectance(const ReflectanceOptions& options, const ReflectanceStack& stack,
                                  const cv::Mat& normals, const cv::Mat& mask, ReflectanceMaps* maps) {
  core::SolveTimer timer;
  ReflectanceSummary summary;
  if (!CheckInputs(options, stack, normals, mask, maps, &summary)) return summary;
  cv::Mat flags;
  internal::Samples s =
      internal::Gather(stack, normals, mask, options.min_cosine, &flags, &summary.saturated_samples);
  const std::vector<int> active = internal::ActivePixels(s, options.min_samples, &flags);
  internal::CountUnfitted(flags, &summary);
  if (active.empty()) {
    summary.End(core::Termination::kFailure, "no pixel has a normal and " + std::to_string(options.min_samples) +
                                           " lit, unsaturated samples; check the mask, the normals and the exposure");
    return summary;
  }
  timer.SetupDone(&summary);

  const internal::OwnLobes own = internal::WeightByNoise(stack.noise, active, options.progress, &s, &summary);
  const internal::PixelClasses classes = internal::ClassifyPixels(options, s, active, own);
  if (classes.clustered.empty()) {
    summary.End(core::Termination::kFailure, "every pixel mixes two colours or the background (" +
                                           std::to_string(classes.mixed.size()) +
                                           " mixed pixels); no material can be chosen");
    return summary;
  }

  std::vector<brdf::Model> candidates{brdf::Model::kLambertian};
  candidates.insert(candidates.end(), options.lobes.begin(), options.lobes.end());
  internal::Partition best = internal::ChooseMaterials(options, s, classes, candidates, &summary.bic_by_materials);
  summary.materials_merged = internal::MergeOnePaintSplits(options, s, candidates, &best);
  if (internal::AssignUnseen(s, classes.chroma, classes.unseen, options.split_alpha,
                             [&] {
                               std::vector<MaterialFit> fits;
                               for (const auto& m : best.materials) fits.push_back(m.fit);
                               return fits;
                             }(),
                             &best.groups)) {
    // A paint no pixel of which saw a highlight: its lobe is what its own
    // pixels show (mostly none), never a neighbouring paint's.
    best.materials.push_back(internal::FitMaterial(s, best.groups.back(), candidates, {}, options.shape_search_pixels));
    ++summary.materials_unobserved;
  }

  internal::FittedPixels fitted =
      internal::FitMaterialPixels(options, s, normals, classes, best, &flags, maps, &summary);
  internal::AssignMixed(options, s, classes.mixed, &fitted, &flags, maps, &summary);
  internal::CheckLightIntensities(options, s, active, fitted, *maps, &summary);
  maps->flags = flags;
  maps->highlight_seen = cv::Mat(s.height, s.width, CV_8U, cv::Scalar(255));
  for (int p : active) {
    if (maps->material.at<std::uint8_t>(s.pixel_index[p]) == 255) continue;
    maps->highlight_seen.at<std::uint8_t>(s.pixel_index[p]) = classes.seen[p];
    summary.pixels_highlight_unseen += !classes.seen[p];
  }
  Conclude(active, fitted, *maps, &summary);
  timer.Finish(&summary);
  return summary;
}

}  // namespace photorig::solvers::reflectance
