#pragma once
// Colour image stacks: the frames of a colour run (Bayer raw or RGB) or of an
// RGB DiLiGenT folder as linear 3-channel float images, after demosaicing and
// the rig's colour model, with their lights. The input of colour photometric
// stereo and of anything else that fits reflectance per channel.
//
// Units: each image is dark-subtracted camera signal in DN, turned by the
// colour model into linear sRGB (or left in camera RGB when there is no model)
// without changing its scale: a model that is homogeneous of degree one
// (linear, root-polynomial) commutes with exposure, so
//   images[k](p)_c / light_scales[k]_c = rho_c(p) / pi * (n . w_k)
// for a Lambertian surface, rho_c its albedo in that space. A perfect white
// reflector has albedo 1 in the green camera channel (the normalisation the
// colour model's exposure scale assumes; docs/color.md).

#include "photorig/daemon/capture/run_store.h"
#include "photorig/solvers/color/apply.h"
#include "photorig/solvers/color/model.h"
#include "photorig/config/color_model.h"

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace photorig::daemon {

// One-channel raw (CV_16U or CV_8U) -> (R, G, B) of the same depth, through
// solvers::color::Demosaic. Throws std::invalid_argument with its message for an
// unknown pattern or a multi-channel raw.
cv::Mat DemosaicToRgb(const cv::Mat& raw, const std::string& pattern, solvers::color::DemosaicMethod method);

// Where a colour stack's numbers came from, for report.json "color".
struct ColorProvenance {
  std::string mosaic = "mono";  // as stored: a Bayer pattern or "RGB"
  std::string demosaic;         // DemosaicMethodName, or "none" for RGB frames
  std::string color_space;      // "linear-srgb" (a colour model was applied) or "camera-rgb"
  std::string color_model_path;  // "" without a model
  std::string color_model_hash;
  std::string color_model_kind;  // e.g. "root-poly-2"
  std::string light_colors;      // where the per-channel light scales came from
};
nlohmann::json ToJson(const ColorProvenance& provenance);

struct ColorStackOptions {
  // bilinear (the default) or edge-aware: photorig/solvers/color/apply.h
  solvers::color::DemosaicMethod demosaic = solvers::color::DemosaicMethod::kBilinear;
  // The colour model file; empty: the one the run's manifest names (the rig's
  // camera.color_model at capture), if any; without one the stack stays in
  // camera RGB.
  std::string color_model_path;
  // Optional CV_8U labels of the frames' size (a material map; 255 = none):
  // the labels along the regions' edges are settled by the raw sites
  // (solvers::color::RegionEdgeVote), then Bayer frames are demosaiced within them
  // (solvers::color::DemosaicWithinRegions), whatever `demosaic` says, so no colour
  // blends across a region's edge. Empty: `demosaic` over the whole frame.
  cv::Mat demosaic_regions;
  // False: the regions are used as given, not settled first (to read a run
  // again exactly as it was read, with the regions it was read with). Default true.
  bool settle_region_edges = true;
};

struct ColorImageStack {
  // K frames, CV_32FC3 (R, G, B), dark subtracted, linear. Samples whose raw
  // value (or any raw value the demosaic drew on) was clipped are +infinity.
  std::vector<cv::Mat> images;
  std::vector<Eigen::Vector3d> light_directions;  // K unit vectors towards the lights
  std::vector<Eigen::Vector3d> light_scales;      // K per-channel scales (see above)
  // Read noise of each channel after demosaicing and the colour model (DN),
  // from the dark frames; 0 when unknown.
  Eigen::Vector3d read_sigma = Eigen::Vector3d::Zero();
  ColorProvenance provenance;
  // For a Bayer run: where it was read from and how (with the regions as
  // settled at their edges), so it can be read again demosaiced within
  // regions (LoadRunColorStack); empty otherwise.
  std::string bayer_run_directory;
  ColorStackOptions loaded_with;
  int region_edges_moved = 0;  // pixels whose label the raw sites changed (solvers::color::RegionEdgeVote)

  int width() const { return images.empty() ? 0 : images.front().cols; }
  int height() const { return images.empty() ? 0 : images.front().rows; }
  int light_count() const { return static_cast<int>(images.size()); }
};


// Reads a run whose manifest records a colour mosaic. Throws ConfigError for
// a bad model file, std::runtime_error naming the file for unreadable frames,
// and std::invalid_argument for a monochrome run.
ColorImageStack LoadRunColorStack(const std::string& run_directory, const ColorStackOptions& options);

// Applies a colour model (camera RGB in DN -> linear sRGB at the same scale)
// to a CV_32FC3 (R, G, B) image in place; +infinity stays +infinity.
void ApplyColorModelInPlace(const solvers::color::ColorModel& model, cv::Mat* rgb);

}  // namespace photorig::daemon
