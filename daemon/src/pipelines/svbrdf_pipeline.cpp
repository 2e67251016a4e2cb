
#include "photorig/daemon/pipelines/svbrdf_pipeline.h"

#include "photorig/daemon/io/json_fields.h"

#include "photorig/solvers/color/region_demosaic.h"
#include "photorig/daemon/io/gltf_export.h"
#include "photorig/daemon/io/image_io.h"
#include "photorig/daemon/io/internal/previews.h"
#include "photorig/daemon/pipelines/internal/results_folder.h"
#include "photorig/solvers/ps/evaluation.h"
#include "photorig/solvers/reflectance/gltf_material.h"
#include "photorig/solvers/core/summary_json.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numeric>
#include <stdexcept>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
namespace refl = solvers::reflectance;
namespace brdf = solvers::brdf;

nlohmann::json MaterialJson(const refl::MaterialFit& m) {
  nlohmann::json j;
  j["model"] = brdf::ModelName(m.model);
  j["pixels"] = m.pixels;
  j["specular"] = {m.specular[0], m.specular[1], m.specular[2]};
  j["specular_sigma"] = {m.specular_sigma[0], m.specular_sigma[1], m.specular_sigma[2]};
  j["shape"] = m.shape;
  j["shape_relative_sigma"] = m.shape_sigma;
  j["rms_residual"] = m.rms_residual;
  j["bic"] = m.bic;
  j["bic_lambertian"] = m.bic_lambertian;
  j["min_half_angle_deg"] = m.min_half_angle_deg;
  j["highlight_lights"] = m.highlight_lights;
  j["highlight_pixels"] = m.highlight_pixels;
  // A lobe (or its absence) is measured only where most of the material's
  // pixels saw a highlight; otherwise it is what a few pixels show, or nothing.
  j["lobe_measured"] = std::find(m.warnings.begin(), m.warnings.end(), refl::Warning::kHighlightsUnobserved) ==
                       m.warnings.end();
  j["warnings"] = nlohmann::json::array();
  for (refl::Warning w : m.warnings) j["warnings"].push_back(refl::WarningName(w));
  return j;
}

// Fraction of the unflagged pixels with a true material (truth < 255) whose
// fitted material is the true one, under the one-to-one relabelling of
// fitted materials that agrees best (tried exhaustively: a handful of labels).
std::optional<double> MaterialAgreement(const refl::ReflectanceMaps& maps, const cv::Mat& truth, int* pixels) {
  if (truth.type() != CV_8U || truth.size() != maps.material.size()) return std::nullopt;
  int labels = static_cast<int>(maps.materials.size());
  for (int i = 0; i < static_cast<int>(truth.total()); ++i)
    if (truth.at<std::uint8_t>(i) != 255) labels = std::max(labels, truth.at<std::uint8_t>(i) + 1);
  if (labels > 8) return std::nullopt;  // 8! relabellings at most
  std::vector<long long> counts(static_cast<std::size_t>(labels) * labels, 0);  // [fitted][true]
  *pixels = 0;
  for (int i = 0; i < static_cast<int>(truth.total()); ++i) {
    const int t = truth.at<std::uint8_t>(i), m = maps.material.at<std::uint8_t>(i);
    if (t == 255 || m >= labels || maps.flags.at<std::uint8_t>(i) != static_cast<std::uint8_t>(refl::PixelFlag::kFitted))
      continue;
    ++counts[static_cast<std::size_t>(m) * labels + t];
    ++*pixels;
  }
  if (*pixels == 0) return std::nullopt;
  std::vector<int> relabel(labels);
  std::iota(relabel.begin(), relabel.end(), 0);
  long long best = 0;
  do {
    long long agree = 0;
    for (int m = 0; m < labels; ++m) agree += counts[static_cast<std::size_t>(m) * labels + relabel[m]];
    best = std::max(best, agree);
  } while (std::next_permutation(relabel.begin(), relabel.end()));
  return static_cast<double>(best) / *pixels;
}

nlohmann::json ColorErrorJson(const PhotometricStereoResult::ColorError& e) {
  return {{"mean", e.mean}, {"median", e.median}, {"p95", e.p95}, {"pixels", e.pixels}};
}

// The material map for demosaicing within materials. A pixel the fit left
// without a material (a blend no material explained, too few samples, a poor
// fit) takes its nearest labelled pixel's, so its channels come from one side
// of an edge and the raw sites settle which (solvers::color::RegionEdgeVote). A pixel
// whose 3 x 3 window reaches off the object (masked out, no normal) is left
// unlabelled, given a material or not: at the rim the object covers part of
// a pixel, and its site would carry the background into its neighbours.
cv::Mat MaterialsOverTheObject(const refl::ReflectanceMaps& maps) {
  cv::Mat off_object(maps.flags.size(), CV_8U, cv::Scalar(0));
  for (int i = 0; i < static_cast<int>(off_object.total()); ++i) {
    const auto flag = static_cast<refl::PixelFlag>(maps.flags.data[i]);
    off_object.data[i] = flag == refl::PixelFlag::kOutsideMask || flag == refl::PixelFlag::kNoNormal ? 255 : 0;
  }
  cv::Mat near_off_object;
  cv::dilate(off_object, near_off_object, cv::Mat::ones(3, 3, CV_8U), cv::Point(-1, -1), 1, cv::BORDER_CONSTANT,
             cv::Scalar(255));
  const cv::Mat unlabelled = maps.material == solvers::color::kNoRegion;
  cv::Mat out = maps.material.clone();
  out.setTo(solvers::color::kNoRegion, near_off_object);
  if (cv::countNonZero(unlabelled) == static_cast<int>(unlabelled.total())) return out;
  cv::Mat distance, nearest;
  cv::distanceTransform(unlabelled, distance, nearest, cv::DIST_L2, cv::DIST_MASK_5, cv::DIST_LABEL_PIXEL);
  // DIST_LABEL_PIXEL gives each labelled pixel an index of its own; map indices to materials.
  std::vector<std::uint8_t> material_of(static_cast<std::size_t>(unlabelled.total()) + 1, solvers::color::kNoRegion);
  for (int i = 0; i < static_cast<int>(maps.material.total()); ++i)
    if (!unlabelled.data[i]) material_of[static_cast<std::size_t>(nearest.ptr<int>()[i])] = maps.material.data[i];
  for (int i = 0; i < static_cast<int>(out.total()); ++i)
    if (unlabelled.data[i] && !near_off_object.data[i])
      out.data[i] = material_of[static_cast<std::size_t>(nearest.ptr<int>()[i])];
  return out;
}

// A bilinear demosaic fills a pixel's missing channels from its neighbours on
// both sides of a paint edge, so the pixels along every edge carry a blend of
// two albedos (flagged mixed, their colour off by CIEDE2000 ~10). Once the
// materials are known the raw frames are demosaiced again, each pixel's
// channels taken only from sites of its own material (its label first
// settled by its own site: solvers::color::RegionEdgeVote), and the reflectance is
// refitted once. Repeating until the map stops changing was tried before
// the colour test of unseen pixels compared them under the material's lobe:
// it moved no more edges, and split a glossy paint's rim off as a paint of
// its own. With that test mended the loop was not brought back
// (docs/reflectance.md).
void RefitDemosaicedWithinMaterials(const PhotometricStereoInput& input, const cv::Mat& normals,
                                    const refl::ReflectanceOptions& options, refl::ReflectanceStack* stack,
                                    refl::ReflectanceMaps* maps, SvbrdfResult* result) {
  ColorStackOptions within = input.color->loaded_with;
  within.demosaic_regions = MaterialsOverTheObject(*maps);
  PhotometricStereoInput regional = input;
  regional.color = LoadRunColorStack(input.color->bayer_run_directory, within);
  refl::ReflectanceStack refit_stack = ToReflectanceStack(regional);
  refit_stack.near_lights = stack->near_lights;  // the same pixels see the same LEDs and camera
  refit_stack.points_mm = stack->points_mm;
  refit_stack.views = stack->views;
  refl::ReflectanceMaps refit;
  const refl::ReflectanceSummary summary = refl::FitReflectance(options, refit_stack, normals, input.object_mask, &refit);
  // A refit that fails keeps the first fit, and the report says why.
  if (!summary.IsSolutionUsable()) {
    result->demosaic_refit_failure = summary.message;
    return;
  }
  *stack = std::move(refit_stack);
  *maps = std::move(refit);
  result->summary = summary;
  result->demosaic = regional.color->provenance.demosaic;
  result->region_edges_moved = regional.color->region_edges_moved;
  result->demosaic_regions = regional.color->loaded_with.demosaic_regions;
  result->fit_passes = 2;
}

}  // namespace

refl::ReflectanceStack ToReflectanceStack(const PhotometricStereoInput& input) {
  refl::ReflectanceStack stack;
  const solvers::ps::PhotometricStack& ps = input.stack;
  // Clipped samples become +max so the solver's saturation test finds them
  // after the dark has been subtracted.
  const float clipped = std::numeric_limits<float>::max();
  if (input.color) {
    // Colour runs: reflectance is fitted per channel on the demosaiced,
    // colour-corrected frames, whose clipped samples are already +infinity.
    const ColorImageStack& color = *input.color;
    bool any_clipped = false;
    for (const cv::Mat& frame : color.images) {
      cv::Mat image = frame.clone();
      const cv::Mat infinite = image == std::numeric_limits<float>::infinity();
      if (cv::countNonZero(infinite.reshape(1)) > 0) {
        any_clipped = true;
        image.setTo(cv::Scalar::all(clipped), infinite);
      }
      stack.images.push_back(image);
    }
    stack.light_directions = color.light_directions;
    stack.light_intensities = color.light_scales;
    stack.view_direction = ps.view_direction;
    // The darks give each processed channel's read noise; the shot noise after
    // demosaicing and the colour model is left to the solver to estimate.
    stack.noise.read_sigma = color.read_sigma;
    if (any_clipped) stack.saturation_level = clipped;
    return stack;
  }
  const double saturation = EffectiveSaturationLevel(input);
  for (std::size_t j = 0; j < ps.images.size(); ++j) {
    cv::Mat image;
    if (ps.dark.empty()) image = ps.images[j].clone(); else image = ps.images[j] - ps.dark;
    if (std::isfinite(saturation)) image.setTo(clipped, ps.images[j] >= saturation);
    stack.images.push_back(image);
    stack.light_intensities.push_back(Eigen::Vector3d::Constant(ps.light_scales.empty() ? 1.0 : ps.light_scales[j]));
  }
  // The rig's noise model: read noise from the darks, shot noise from the camera's electrons per DN.
  stack.noise.read_sigma.setConstant(ps.noise.read_sigma);
  stack.noise.shot_gain.setConstant(ps.noise.shot_gain);
  stack.light_directions = ps.light_directions;
  stack.view_direction = ps.view_direction;
  if (std::isfinite(saturation)) stack.saturation_level = clipped;
  return stack;
}

namespace {

// The surface a near-light solve placed (heights in mm), or empty.
cv::Mat NearSurface(const PhotometricStereoResult& ps, const fs::path& ps_directory) {
  if (!ps.light_model.near || !ps.depth || !ps.depth->from_near_lights || !fs::exists(ps_directory / "depth.tiff"))
    return {};
  return ReadFloatTiff((ps_directory / "depth.tiff").string());
}

}  // namespace

std::string AddPixelGeometry(const PhotometricStereoInput& input, bool near, const cv::Mat& height_mm,
                             refl::ReflectanceStack* stack) {
  const solvers::camera::Camera camera = CameraOf(input);
  if (!near && !camera.IsPinhole()) return {};  // every pixel sees the stack's directions and view
  const solvers::camera::PixelRays rays(camera);
  const int rows = input.stack.height(), cols = input.stack.width();
  if (camera.IsPinhole()) stack->views = rays.ViewDirections();
  if (!near) return {};
  if (height_mm.size() != cv::Size(cols, rows) || height_mm.type() != CV_32F)
    return "the rig's LEDs are near: the reflectance fits need the surface the photometric-stereo solve placed "
           "(its depth.tiff); solve with an integrator";
  stack->near_lights = input.near_lights;
  stack->points_mm.create(rows, cols, CV_32FC3);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      // An unsolved pixel gets no reflectance; its point only has to be finite.
      const float z = height_mm.at<float>(r, c);
      const Eigen::Vector3d point = rays.Point(r, c, std::isfinite(z) ? z : 0.0);
      stack->points_mm.at<cv::Vec3f>(r, c) = cv::Vec3f(float(point.x()), float(point.y()), float(point.z()));
    }
  return {};
}

nlohmann::json ToJson(const SvbrdfResult& result) {
  nlohmann::json j = solvers::core::ToJson(result.summary);
  j["source"] = result.ps.source;
  if (result.ps.capture) j["capture"] = result.ps.capture->ToJson();
  j["pixels"] = {{"fitted", result.summary.pixels_fitted},
                 {"outside_mask", result.summary.pixels_outside_mask},
                 {"no_normal", result.summary.pixels_no_normal},
                 {"too_few_samples", result.summary.pixels_too_few_samples},
                 {"poor_fit", result.summary.pixels_poor_fit},
                 {"mixed", result.summary.pixels_mixed},
                 {"mixed_assigned", result.summary.pixels_mixed_assigned},
                 {"highlight_unseen", result.summary.pixels_highlight_unseen}};
  j["saturated_samples"] = result.summary.saturated_samples;
  if (!result.previews.is_null()) j["previews"] = result.previews;
  j["materials"] = nlohmann::json::array();
  for (std::size_t m = 0; m < result.material_fits.size(); ++m) {
    nlohmann::json mj = MaterialJson(result.material_fits[m]);
    if (m < result.gltf_mapping_error.size()) mj["gltf_mapping_error"] = result.gltf_mapping_error[m];
    j["materials"].push_back(mj);
  }
  j["bic_by_materials"] = result.summary.bic_by_materials;
  j["materials_merged"] = result.summary.materials_merged;
  j["materials_unobserved"] = result.summary.materials_unobserved;
  const refl::SensorNoise& noise = result.summary.noise;
  j["noise"] = {{"source", result.summary.noise_source},
                {"read_sigma", {noise.read_sigma[0], noise.read_sigma[1], noise.read_sigma[2]}},
                {"shot_gain", {noise.shot_gain[0], noise.shot_gain[1], noise.shot_gain[2]}},
                {"relative", {noise.relative[0], noise.relative[1], noise.relative[2]}},
                {"reduced_chi_square", result.summary.reduced_chi_square}};
  j["warnings"] = nlohmann::json::array();
  for (refl::Warning w : result.summary.warnings) j["warnings"].push_back(refl::WarningName(w));
  j["inconsistent_lights"] = result.summary.inconsistent_lights;
  j["options"] = {{"max_materials", result.max_materials}, {"refine_normals", result.normal_refinement.has_value()}};
  if (result.normal_refinement) {
    const refl::NormalRefinementSummary& n = *result.normal_refinement;
    nlohmann::json& nj = j["normal_refinement"];
    nj = solvers::core::ToJson(n);
    nj.update({{"rounds", n.rounds},
               {"pixels_refined", n.pixels_refined},
               {"pixels_held", n.pixels_held},
               {"median_change_deg", n.median_change_deg},
               {"p95_change_deg", n.p95_change_deg},
               {"reduced_chi_square_before", n.reduced_chi_square_before},
               {"reduced_chi_square_after", n.reduced_chi_square_after},
               {"kept", n.kept_refined ? "refined" : "given"},
               {"held_out_rmse", {{"given", n.held_out_rmse_given}, {"refined", n.held_out_rmse_refined}}}});
    nj["timings_ms"].update({{"normals", n.normals_ms}, {"judge", n.judge_ms}});
    if (result.refined_normals_vs_truth_mean_deg)
      nj["normals_vs_truth_mean_deg"] = {{"before", *result.unrefined_normals_vs_truth_mean_deg},
                                         {"after", *result.refined_normals_vs_truth_mean_deg}};
  }
  j["demosaic"] = {{"method", result.demosaic}, {"fit_passes", result.fit_passes},
                   {"region_edges_moved", result.region_edges_moved}};
  if (!result.demosaic_refit_failure.empty()) j["demosaic"]["refit_failure"] = result.demosaic_refit_failure;
  j["timings_ms"]["pipeline"] = result.total_ms;
  if (result.ps.normals_vs_truth)
    j["normals_vs_truth_deg"] = {{"mean", result.ps.normals_vs_truth->mean_deg},
                                 {"median", result.ps.normals_vs_truth->median_deg}};
  if (result.albedo_error_vs_truth) j["albedo_median_relative_error_vs_truth"] = *result.albedo_error_vs_truth;
  if (result.albedo_ciede2000_unflagged) {
    nlohmann::json& e = j["albedo_ciede2000_vs_truth"];
    e["unflagged"] = ColorErrorJson(result.albedo_ciede2000_unflagged->all);
    e["unflagged_interior"] = ColorErrorJson(result.albedo_ciede2000_unflagged->interior);
    e["with_albedo"] = ColorErrorJson(result.albedo_ciede2000_with_albedo->all);
  }
  if (result.material_agreement)
    j["material_agreement_vs_truth"] = {{"fraction", *result.material_agreement},
                                        {"pixels", result.material_agreement_pixels}};
  if (result.relighting) {
    const refl::RelightingSummary& r = *result.relighting;
    nlohmann::json h = solvers::core::ToJson(r);
    h["subset"] = "stratified (farthest-point over the light directions)";
    h["lights"] = r.held_out;
    for (int m = 0; m < 3; ++m) {
      const char* name = refl::MethodName(static_cast<refl::Method>(m));
      h["mean"][name] = {{"rmse", r.mean_rmse[m]}, {"psnr_db", r.mean_psnr_db[m]}, {"fit_ms", r.mean_fit_ms[m]}};
    }
    h["by_material"] = nlohmann::json::array();
    for (const auto& rmse : r.material_rmse) {
      nlohmann::json mj;
      for (int m = 0; m < 3; ++m) mj[refl::MethodName(static_cast<refl::Method>(m))] = rmse[m];
      h["by_material"].push_back(mj);
    }
    h["errors"] = nlohmann::json::array();
    for (const auto& e : r.errors)
      h["errors"].push_back({{"light", e.light}, {"method", refl::MethodName(e.method)}, {"rmse", e.rmse},
                             {"psnr_db", e.psnr_db}, {"fit_ms", e.fit_ms}});
    j["held_out"] = h;
  }
  if (!result.gltf_path.empty()) j["gltf"] = fs::path(result.gltf_path).lexically_relative(fs::path(result.gltf_path).parent_path().parent_path()).string();
  return j;
}

SvbrdfResult SolveSvbrdfAndWrite(const PhotometricStereoInput& input, const config::SvbrdfRequest& request,
                                 const std::string& output_directory) {
  const auto start = std::chrono::steady_clock::now();
  // Refused before the solve, which would end with the relighting check refusing it.
  if (request.held_out_lights > input.stack.light_count())
    throw std::invalid_argument("held-out lights: " + std::to_string(request.held_out_lights) + " exceeds the " +
                                std::to_string(input.stack.light_count()) + " lights of " + input.source +
                                " (0 holds out every light, -1 none)");
  // Whole or not at all, like photometric stereo's folder (results_folder.h).
  ResultsFolder folder(output_directory);
  const fs::path out(folder.path());
  SvbrdfResult result;
  result.max_materials = request.max_materials;
  try {
    config::PhotometricStereoRequest ps_request = request.ps;
    ps_request.progress = request.progress;
    result.ps = SolveAndWrite(input, ps_request, (out / "ps").string());
    refl::ReflectanceStack stack = ToReflectanceStack(input);
    const std::string geometry_why =
        result.ps.usable() ? AddPixelGeometry(input, result.ps.light_model.near, NearSurface(result.ps, out / "ps"), &stack)
                           : std::string();
    if (!result.ps.usable()) {
      result.summary.End(solvers::core::Termination::kFailure, "photometric stereo found no normals: " + result.ps.summary.message);
    } else if (!geometry_why.empty()) {
      result.summary.End(solvers::core::Termination::kFailure, geometry_why);
    } else {
      cv::Mat normals = ReadFloatTiff((out / "ps" / "normals.tiff").string());
      cv::Mat mask = input.object_mask;
      refl::ReflectanceOptions options;
      options.max_materials = request.max_materials;
      options.progress = request.progress;
      refl::ReflectanceMaps maps;
      result.summary = refl::FitReflectance(options, stack, normals, mask, &maps);
      result.demosaic = input.color ? input.color->provenance.demosaic : "none";
      result.fit_passes = 1;
      if (result.summary.IsSolutionUsable() && input.color && !input.color->bayer_run_directory.empty())
        RefitDemosaicedWithinMaterials(input, normals, options, &stack, &maps, &result);
      if (result.summary.IsSolutionUsable() && request.refine_normals) {
        refl::NormalRefinementOptions refine;
        refine.fit = options;
        refine.progress = request.progress;
        cv::Mat refined;
        refl::ReflectanceMaps refined_maps;
        result.normal_refinement =
            refl::RefineNormalsAndReflectance(refine, stack, normals, mask, maps, result.summary, &refined, &refined_maps);
        if (result.normal_refinement->IsSolutionUsable() && result.normal_refinement->rounds > 0) {
          if (!input.truth_normals.empty()) {
            const cv::Mat fitted = refined_maps.material != solvers::color::kNoRegion;
            result.unrefined_normals_vs_truth_mean_deg = solvers::ps::CompareNormals(normals, input.truth_normals, fitted).mean_deg;
            result.refined_normals_vs_truth_mean_deg = solvers::ps::CompareNormals(refined, input.truth_normals, fitted).mean_deg;
          }
          normals = refined;
          maps = std::move(refined_maps);
          result.summary = result.normal_refinement->reflectance;
          // Given normals kept (the refined ones predicted the held-out lights no better): ps/normals.tiff stands.
          if (result.normal_refinement->kept_refined) WriteFloatTiff((out / "normals.tiff").string(), normals);
        }
      }
      if (result.summary.IsSolutionUsable()) {
        result.material_fits = maps.materials;
        WriteFloatTiff((out / "albedo.tiff").string(), maps.albedo);
        WriteFloatTiff((out / "albedo_sigma.tiff").string(), maps.albedo_sigma);
        WriteFloatTiff((out / "rms_residual.tiff").string(), maps.rms_residual);
        WriteImage((out / "material.png").string(), maps.material);
        WriteImage((out / "flags.png").string(), CategoricalPreview(maps.flags, ReflectanceFlagCategories()));
        result.previews["flags.png"] = LegendJson(ReflectanceFlagCategories(), maps.flags);
        WriteImage((out / "highlight_seen.png").string(), maps.highlight_seen);
        if (!result.demosaic_regions.empty()) WriteImage((out / "demosaic_regions.png").string(), result.demosaic_regions);
        for (const auto& m : maps.materials)
          result.gltf_mapping_error.push_back(refl::GltfMappingError(m, stack.light_directions, stack.view_direction));
        const int C = maps.albedo.channels();
        if (!input.truth_albedo.empty() && input.truth_albedo.size() == maps.albedo.size()) {
          std::vector<double> errors;
          for (int i = 0; i < static_cast<int>(maps.flags.total()); ++i) {
            if (maps.flags.at<std::uint8_t>(i) != static_cast<std::uint8_t>(refl::PixelFlag::kFitted)) continue;
            const double t = input.truth_albedo.ptr<float>()[i];
            double f = 0.0;
            for (int ch = 0; ch < C; ++ch) f += maps.albedo.ptr<float>()[i * C + ch] / C;
            if (std::isfinite(t) && t > 0.0) errors.push_back(std::abs(f - t) / t);
          }
          if (!errors.empty()) {
            std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
            result.albedo_error_vs_truth = errors[errors.size() / 2];
          }
        }
        if (!input.truth_albedo_rgb.empty() && C == 3 && input.truth_albedo_rgb.size() == maps.albedo.size()) {
          const cv::Mat unflagged = maps.flags == static_cast<int>(refl::PixelFlag::kFitted);
          const cv::Mat with_albedo = maps.material != 255;
          result.albedo_ciede2000_unflagged = CompareColorAlbedo(maps.albedo, input.truth_albedo_rgb, unflagged);
          result.albedo_ciede2000_with_albedo = CompareColorAlbedo(maps.albedo, input.truth_albedo_rgb, with_albedo);
        }
        if (!input.truth_material.empty())
          result.material_agreement = MaterialAgreement(maps, input.truth_material, &result.material_agreement_pixels);
        if (request.held_out_lights >= 0) {
          refl::RelightingOptions relight;
          relight.fit = options;
          relight.fit.progress = nullptr;
          relight.held_out_lights = request.held_out_lights;
          relight.progress = request.progress;
          result.relighting = refl::EvaluateHeldOutLights(relight, stack, normals, mask, maps, result.summary);
        }
        if (request.export_gltf && fs::exists(out / "ps" / "depth.tiff")) {
          const cv::Mat depth = ReadFloatTiff((out / "ps" / "depth.tiff").string());
          result.gltf_path = WriteGltfAsset((out / "asset").string(), maps, depth, solvers::camera::PixelRays(CameraOf(input))).gltf_path;
        }
      }
    }
    result.total_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    WriteFileDurably((out / "report.json").string(), ToJson(result).dump(2) + "\n");
  } catch (...) {
    folder.Abandon(std::current_exception());
  }
  folder.Commit();
  if (!result.gltf_path.empty())  // it was written inside the partial folder
    result.gltf_path = (fs::path(output_directory) / fs::path(result.gltf_path).lexically_relative(out)).string();
  return result;
}

refl::ReflectanceMaps ReadSvbrdfResult(const std::string& output_directory) {
  const fs::path dir(output_directory);
  const fs::path report_path = dir / "report.json";
  std::ifstream file(report_path);
  if (!file) throw std::runtime_error(report_path.string() + " not found: run `photorig solve svbrdf` first");
  const nlohmann::json report = nlohmann::json::parse(file);
  refl::ReflectanceMaps maps;
  maps.albedo = ReadFloatTiff((dir / "albedo.tiff").string());
  // The refined normals when the solve refined them, else photometric stereo's.
  maps.normals = ReadFloatTiff((fs::exists(dir / "normals.tiff") ? dir / "normals.tiff" : dir / "ps" / "normals.tiff").string());
  maps.material = ReadImage((dir / "material.png").string());
  maps.flags = ReadImage((dir / "flags.png").string());
  // The colours of the legend's categories; a folder written before flags.png
  // had a legend holds the codes themselves.
  if (maps.flags.channels() == 3) maps.flags = CodesFromPreview(maps.flags, maps.albedo.size(), ReflectanceFlagCategories());
  for (const auto& m : report.at("materials")) {
    refl::MaterialFit fit;
    const auto model = brdf::ParseModel(m.at("model").get<std::string>());
    if (!model) throw std::runtime_error(report_path.string() + ": unknown model " + m.at("model").dump());
    fit.model = *model;
    for (int ch = 0; ch < 3; ++ch) fit.specular[ch] = m.at("specular")[ch].get<double>();
    fit.shape = m.at("shape").get<double>();
    try {
      fit.pixels = IntegerAt<int>(m, "pixels");
    } catch (const std::runtime_error& e) {
      throw std::runtime_error(report_path.string() + ": " + e.what());
    }
    maps.materials.push_back(fit);
  }
  return maps;
}

HeldOutLightImages PredictHeldOutLight(const std::string& run_directory, const std::string& svbrdf_directory,
                                       int light) {
  const fs::path dir(svbrdf_directory);
  const fs::path report_path = dir / "report.json";
  std::ifstream file(report_path);
  if (!file) throw std::runtime_error(report_path.string() + " not found: run `photorig solve svbrdf` first");
  const nlohmann::json report = nlohmann::json::parse(file);
  const refl::ReflectanceMaps maps = ReadSvbrdfResult(svbrdf_directory);
  // Read as the solve read it: a Bayer run within the regions it saved (used
  // as they are, not settled again), else with the solve's demosaic.
  ColorStackOptions color;
  if (report.contains("demosaic"))
    color.demosaic = solvers::core::ParseName(solvers::color::kDemosaicMethodNames, report["demosaic"].value("method", ""))
                         .value_or(solvers::color::DemosaicMethod::kBilinear);
  const bool within_regions = fs::exists(dir / "demosaic_regions.png");
  if (within_regions) {
    color.demosaic_regions = ReadImage((dir / "demosaic_regions.png").string());
    color.settle_region_edges = false;
  }
  // The solve that made the result judged the capture (and marked its report).
  const PhotometricStereoInput input = LoadRunStack(run_directory, color, FailedCapture::kAccept);
  if (within_regions && (!input.color || input.color->bayer_run_directory.empty()))
    throw std::runtime_error((dir / "demosaic_regions.png").string() + " names regions, but " + run_directory +
                             " is not a Bayer run");
  if (light < 0 || light >= input.stack.light_count())
    throw std::invalid_argument("light " + std::to_string(light) + " is not one of " + run_directory + "'s " +
                                std::to_string(input.stack.light_count()) + " lights (0.." +
                                std::to_string(input.stack.light_count() - 1) + ")");
  if (maps.flags.size() != input.stack.images.front().size())
    throw std::runtime_error(svbrdf_directory + " is not a solve of " + run_directory + ": its maps are " +
                             std::to_string(maps.flags.cols) + " x " + std::to_string(maps.flags.rows));
  // The solve's mask is where it did not flag a pixel as outside it.
  const cv::Mat mask = maps.flags != static_cast<int>(refl::PixelFlag::kOutsideMask);
  refl::ReflectanceStack stack = ToReflectanceStack(input);
  // Seen as the solve saw it: under near LEDs, from the surface it placed.
  std::ifstream ps_file(dir / "ps" / "report.json");
  const nlohmann::json ps_report = ps_file ? nlohmann::json::parse(ps_file, nullptr, false) : nlohmann::json();
  const bool near = ps_report.is_object() && ps_report.contains("light_model") &&
                    ps_report["light_model"].value("model", std::string()) == "near";
  const cv::Mat surface = near && fs::exists(dir / "ps" / "depth.tiff") ? ReadFloatTiff((dir / "ps" / "depth.tiff").string()) : cv::Mat();
  if (const std::string why = AddPixelGeometry(input, near, surface, &stack); !why.empty())
    throw std::runtime_error(svbrdf_directory + ": " + why);
  refl::RelightingOptions options;
  options.fit.max_materials = report.contains("options") ? report["options"].value("max_materials", 4) : 4;
  options.lights = {light};
  options.keep_predictions = true;
  refl::ReflectanceMaps full;
  const refl::ReflectanceSummary fitted = refl::FitReflectance(options.fit, stack, maps.normals, mask, &full);
  HeldOutLightImages out;
  if (!fitted.IsSolutionUsable()) {
    out.summary.End(fitted.termination, "the fit on every light: " + fitted.message);
    return out;
  }
  out.summary = refl::EvaluateHeldOutLights(options, stack, maps.normals, mask, full, fitted);
  out.measured = stack.images[light].clone();
  if (std::isfinite(stack.saturation_level))
    out.measured.setTo(cv::Scalar::all(std::numeric_limits<float>::quiet_NaN()),
                       stack.images[light] >= stack.saturation_level);
  return out;
}

}  // namespace photorig::daemon
