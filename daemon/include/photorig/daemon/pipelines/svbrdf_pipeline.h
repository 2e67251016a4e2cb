#pragma once
// `photorig solve svbrdf`: photometric stereo for the normals and the depth,
// then spatially varying reflectance (solvers/reflectance) on the same stack,
// its held-out-light relighting check, and the glTF asset.
//
// Output directory:
//   ps/                    the photometric-stereo result (normals, depth, mesh, its report.json)
//   albedo.tiff            rho_d, float, 1 or 3 channels
//   albedo_sigma.tiff      its standard deviation
//   material.png           material index per pixel (255 = not fitted)
//   flags.png              solvers::reflectance::PixelFlag per pixel
//   rms_residual.tiff      per-pixel RMS residual (image units)
//   demosaic_regions.png   for a Bayer run: the labels the frames were demosaiced within (255 = none)
//   normals.tiff           with refine_normals: the refined normals the reflectance was fitted with
//   asset/                 asset.gltf, asset.bin, PNG textures, EXR maps (gltf_export.h)
//   report.json            materials with their lobes, warnings, held-out errors, timings, truth comparisons

#include "photorig/daemon/pipelines/ps_pipeline.h"
#include "photorig/solvers/reflectance/fit.h"
#include "photorig/solvers/reflectance/normal_refinement.h"
#include "photorig/solvers/reflectance/relighting.h"

#include <nlohmann/json.hpp>

#include <optional>
#include <string>

namespace photorig::daemon {


// The stack as the reflectance solver takes it: dark subtracted, light
// scales as per-channel intensities, clipped samples marked so the solver
// leaves them out and counts them.
solvers::reflectance::ReflectanceStack ToReflectanceStack(const PhotometricStereoInput& input);

// Each pixel's own view of the LEDs and the camera where the rig makes them
// differ over the image: with `near`, the rig's LED positions seen from the
// surface the photometric-stereo solve placed (height_mm: its depth.tiff,
// heights in mm, NaN where unsolved); for a pinhole camera, every pixel's
// line of sight. Empty, or why it cannot (near LEDs without that surface).
std::string AddPixelGeometry(const PhotometricStereoInput& input, bool near, const cv::Mat& height_mm,
                             solvers::reflectance::ReflectanceStack* stack);

struct SvbrdfResult {
  PhotometricStereoResult ps;
  solvers::reflectance::ReflectanceSummary summary;
  std::vector<solvers::reflectance::MaterialFit> material_fits;  // as fitted, for the report
  std::optional<solvers::reflectance::RelightingSummary> relighting;
  // With SvbrdfRequest::refine_normals: the alternation's summary, and the
  // mean angle to the true normals before and after it where the truth is known.
  std::optional<solvers::reflectance::NormalRefinementSummary> normal_refinement;
  std::optional<double> refined_normals_vs_truth_mean_deg, unrefined_normals_vs_truth_mean_deg;
  std::vector<double> gltf_mapping_error;   // per material, relative RMS (gltf_material.h)
  std::optional<double> albedo_error_vs_truth;  // median relative, over fitted pixels
  // Colour runs with true albedo: CIEDE2000 over the unflagged pixels (flag
  // fitted), and over every pixel given an albedo (mixed and poor fits too).
  std::optional<PhotometricStereoResult::ColorErrors> albedo_ciede2000_unflagged, albedo_ciede2000_with_albedo;
  // With a true material map: the fraction of unflagged pixels assigned the
  // true material, under the relabelling of materials that agrees best.
  std::optional<double> material_agreement;
  int material_agreement_pixels = 0;
  // How the fitted colour frames were demosaiced (ColorProvenance::demosaic;
  // "none" for monochrome and RGB frames), and how many fits it took: a Bayer
  // run is refitted once on frames demosaiced within the first fit's
  // materials (2 fits). A refit that failed keeps the first fit and gives its
  // reason here.
  std::string demosaic;
  int fit_passes = 0;
  int region_edges_moved = 0;  // labels the raw sites changed before the refit (solvers::color::RegionEdgeVote)
  std::string demosaic_refit_failure;
  cv::Mat demosaic_regions;  // CV_8U, the labels of the refit's demosaic; empty without one
  int max_materials = 0;     // as requested, for report.json "options" (what a later relight needs to refit)
  nlohmann::json previews;   // {"flags.png": its legend (previews.h LegendJson)}, when fitted
  std::string gltf_path;                    // empty when not exported
  double total_ms = 0.0;
  bool usable() const { return ps.usable() && summary.IsSolutionUsable(); }
};

nlohmann::json ToJson(const SvbrdfResult& result);

// Solves and writes the folder above into `output_directory`, replaced whole
// as it ends (results_folder.h); a write that fails throws ResultsWriteError
// and leaves `output_directory` as it was.
SvbrdfResult SolveSvbrdfAndWrite(const PhotometricStereoInput& input, const config::SvbrdfRequest& request,
                                 const std::string& output_directory);

// Reads back what SolveSvbrdfAndWrite wrote (maps, normals, materials), for relighting.
solvers::reflectance::ReflectanceMaps ReadSvbrdfResult(const std::string& output_directory);

// One held-out light, as `photorig relight --held-out` shows it: the run's
// stack read as the solve in `svbrdf_directory` read it (a Bayer run
// demosaiced within its demosaic_regions.png), the fit on every light made
// again on it (deterministic, so the solve's own), then the light held out
// and predicted by each method from the others. Errors match the solve's
// held_out figures for that light. Throws std::runtime_error naming the file
// when the solve's output is missing or does not fit the run, and
// std::invalid_argument for a light index outside the run's.
struct HeldOutLightImages {
  cv::Mat measured;  // CV_32FC(C), dark subtracted, NaN where clipped
  solvers::reflectance::RelightingSummary summary;  // errors and predictions (one per method)
};
HeldOutLightImages PredictHeldOutLight(const std::string& run_directory, const std::string& svbrdf_directory,
                                       int light);

}  // namespace photorig::daemon
