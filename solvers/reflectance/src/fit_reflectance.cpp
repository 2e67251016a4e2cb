// FitReflectance and its inputs' checks; the fit's stages are in the files
// fit_stages.h lists.
#include "photorig/solvers/reflectance/fit.h"

#include "fit_stages.h"

#include <string>

namespace photorig::solvers::reflectance {

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
