#pragma once
// Photometric stereo on stored data: a run directory or a DiLiGenT-layout
// folder -> solver -> files.
//   normals.tiff        float (x, y, z), NaN where unsolved
//   albedo.tiff         float diffuse albedo
//   confidence.tiff     0..1, how well the chosen model explains the pixel
//   specular.tiff       (rho_s, exponent, 0) where Blinn-Phong was chosen
//   depth.tiff, mesh.ply   integrated depth (units of the pixel pitch) and its triangle mesh
//   angular_error.tiff  degrees, when ground truth exists
//   normals.png, albedo.png, depth.png, confidence.png, mask.png, flags.png, model.png
//                       8-bit views, each mapped from its own data's range (previews.h);
//                       the mappings and the legends are in report.json "previews"
//   report.json         timings, counts, noise model, metrics

#include "photorig/daemon/pipelines/color_stack.h"
#include "photorig/config/recipe.h"
#include "photorig/config/solve_requests.h"
#include "photorig/daemon/capture/run_store.h"
#include "photorig/daemon/pipelines/provenance.h"
#include "photorig/solvers/camera/camera.h"
#include "photorig/solvers/ps/evaluation.h"
#include "photorig/solvers/ps/fill_unresolved.h"
#include "photorig/solvers/ps/integration.h"
#include "photorig/solvers/ps/near_lights.h"
#include "photorig/solvers/ps/photometric_stereo.h"
#include "photorig/solvers/ps/stack.h"

#include <nlohmann/json.hpp>

#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace photorig::daemon {

struct PhotometricStereoInput {
  std::string source;        // run directory or dataset folder, for reports and errors
  solvers::ps::PhotometricStack stack;
  int dark_frames = 0;
  double pixel_pitch = 1.0;  // object-space size of a pixel (mm for rigs that know it), for depth
  // The run's camera (solvers/camera/camera.h); unset: orthographic with pixel_pitch.
  std::optional<solvers::camera::Camera> camera;
  // Samples at or above this are clipped; infinity = unknown, then taken as the
  // full-scale code the data reach, if they reach one.
  double saturation_level = std::numeric_limits<double>::infinity();
  cv::Mat truth_normals;     // optional CV_32FC3 ground truth
  cv::Mat truth_albedo;      // optional CV_32F
  cv::Mat truth_height;      // optional CV_32F, same unit as pixel_pitch
  cv::Mat object_mask;       // optional CV_8U: solve only here (DiLiGenT's mask.png, --mask)
  // One per image when the rig gives its LEDs' positions (mm, the frame of
  // pixel_pitch's grid); empty: distant lights.
  std::vector<solvers::camera::NearLight> near_lights;
  // A run's: the rig LED each image was lit by, and the LEDs as the run
  // recorded them (what ApplyRigCalibration replaces). Empty for a dataset.
  std::vector<int> image_leds;
  std::vector<config::LedConfig> run_leds;
  std::string mask_source;   // where object_mask came from, for the report ("" when there is none)
  // Colour data (a Bayer or RGB run, an RGB DiLiGenT folder): the frames per
  // channel. `stack` is then their channel sum in camera units, on which the
  // normals are solved; each channel's albedo is fitted with those normals fixed.
  std::optional<ColorImageStack> color;
  cv::Mat truth_albedo_rgb;  // optional CV_32FC3 (R, G, B), linear sRGB
  cv::Mat truth_material;    // optional CV_8U material (paint) per pixel, 255 off the object
  // A run's capture verdict (CheckCaptureForSolve); unset for a dataset folder.
  std::optional<CaptureVerdict> capture;
  // How the frames were read, for the result's provenance (provenance.h):
  // "demosaic", "color_model", "accept_failed_capture", and "mask" once a
  // mask file is set.
  nlohmann::json loading = nlohmann::json::object();
};

// The LEDs (directions, positions, axes, exponents, intensities) and camera
// of `rig` in place of those the run recorded: a calibration made after the
// capture, applied to its frames. Throws ConfigError naming the rig file when
// its LEDs or camera do not match the run (count, ids, image size), or for a
// dataset folder, which has no run to re-calibrate.
void ApplyRigCalibration(const std::string& rig_path, PhotometricStereoInput* input);

// Replaces the input's object mask with a PNG file (nonzero = object). Throws
// ConfigError naming the file and both sizes when it does not match the images.
void SetObjectMaskFromFile(const std::string& path, PhotometricStereoInput* input);

// With dark frames and no mask, SolveAndWrite solves only the pixels whose
// brightest lit frame rises above the dark by more than this many read-noise
// sigmas (and by at least 1 DN): the rest see none of the lights, so a normal
// there would be fitted to noise.
inline constexpr double kAutomaticMaskSigmas = 5.0;
cv::Mat AutomaticObjectMask(const solvers::ps::PhotometricStack& stack, double sigmas);

// Reads a run directory (manifest, frames, ground truth). Dark frames are
// averaged and their noise becomes the stack's read noise. Throws
// std::runtime_error naming the file for unreadable or inconsistent runs.
// A colour run (manifest camera.mosaic not "mono") is demosaiced with
// `color.demosaic` and put through its colour model (`color`, else the one the
// manifest names); its `stack` is the sum of the camera channels.
// A run whose capture did not complete is refused (FailedCaptureError) unless
// `failed` accepts it; a run without one frame per LED (a gonioreflectometer
// or tomography run) is refused with std::invalid_argument naming its solver.
PhotometricStereoInput LoadRunStack(const std::string& run_directory, const ColorStackOptions& color = {},
                                    FailedCapture failed = FailedCapture::kRefuse);

// The level at or above which samples count as clipped: the input's own, or,
// for data that do not say (DiLiGenT folders), the full-scale code 2^n - 1
// when the data reach one; infinity when nothing is known to be clipped.
double EffectiveSaturationLevel(const PhotometricStereoInput& input);

// The camera the run's frames were taken with: its rig's, else orthographic
// with the run's pixel pitch.
solvers::camera::Camera CameraOf(const PhotometricStereoInput& input);

// The solver's options for a request that has passed
// ValidatePhotometricStereoRequest; samples at or above saturation_level are
// clipped.
solvers::ps::PhotometricStereoOptions MakeSolverOptions(const config::PhotometricStereoRequest& request, double saturation_level);

// The depth integrated from the solved normals.
struct PhotometricStereoDepth {
  solvers::ps::Integrator integrator = solvers::ps::Integrator::kPoisson;
  solvers::ps::IntegrationSummary summary;
  double pixel_pitch = 1.0;        // depth units per pixel (orthographic)
  bool perspective = false;        // integrated through the run's pinhole camera: heights in mm
  bool from_near_lights = false;   // the near-light solve's own depth, placed by its model fit
  // RMS of depth - true height after removing their mean difference (depth is
  // known up to a constant); when the source has a ground-truth height.
  std::optional<double> rms_error_vs_truth;
};

// Which light model solved the normals, and what it did.
struct LightModelReport {
  bool near = false;  // the near-light model (solvers/ps/near_lights.h); else the distant one
  // For a rig with near LEDs solved with the distant model: the bias that
  // model makes on a sphere the size of the object (DistantModelBiasDeg).
  std::optional<double> predicted_distant_bias_deg;
  int rounds = 0;                         // near: normal solves
  std::vector<double> normal_change_deg;  // near: mean change per round after the first
  double depth_offset_mm = 0.0;           // near: z of the surface's mean depth
  double depth_ms = 0.0;                  // near: of the solve's time, integrating and placing the depth
  // For a pinhole camera solved by a method that models specular reflection
  // under distant lights: the tilt to expect on glossy pixels with the view
  // along the axis (half the mean angle of the object's lines of sight to
  // the axis).
  std::optional<double> predicted_view_bias_deg;
  // Distant lights whose lobes were fitted through each pixel's line of
  // sight, the predicted tilt being above the request's limit.
  bool per_pixel_views = false;
};

// What one solve produced. Callers use it as is; ToJson gives report.json.
struct PhotometricStereoResult {
  std::string source;              // PhotometricStereoInput::source
  int dark_frames = 0;
  double noise_sigma_dn = 0.0;     // the stack's read noise (from its darks)
  double saturation_level = std::numeric_limits<double>::infinity();  // as applied; infinity = nothing clipped
  solvers::ps::SolverSummary summary;       // method, termination, message, pixel counts, noise model, timings
  LightModelReport light_model;
  solvers::camera::Camera camera;  // the camera model the solve used
  // Measured on the output, so only when the solution is usable:
  std::optional<double> mean_confidence;     // over solved pixels
  std::optional<PhotometricStereoDepth> depth;   // unless the request asked for no integrator
  // Normals given to masked pixels left without one, unless the request asked for none.
  std::optional<solvers::ps::FillSummary> fill;
  std::optional<solvers::ps::AngularErrorStats> normals_vs_truth;  // when the source has ground-truth normals (filled pixels too)
  std::optional<solvers::ps::AngularErrorStats> filled_vs_truth;   // ... over the filled pixels alone
  std::optional<double> mean_relative_albedo_error;      // ... and albedo; over solved pixels
  // Colour: where the numbers came from, and CIEDE2000 of the albedo against
  // a linear-sRGB ground truth (CIELAB of D65, white Y = 1) over the solved pixels.
  std::optional<ColorProvenance> color;
  std::optional<solvers::ps::SolverSummary> color_albedo_summary;  // the green channel's fit (the others alike)
  struct ColorError {
    double mean = 0.0, median = 0.0, p95 = 0.0;
    int pixels = 0;
  };
  // Over every solved pixel, and over the interior of each paint: pixels whose
  // true colour is the same over the 5 x 5 pixels around them, away from
  // texture edges (which demosaicing blurs across) and the object's rim.
  struct ColorErrors {
    ColorError all, interior;
  };
  std::optional<ColorErrors> albedo_ciede2000_vs_truth;
  std::optional<CaptureVerdict> capture;  // PhotometricStereoInput::capture
  Provenance provenance;                   // the request and the input it was solved from
  std::string mask_source;         // "" when every pixel was solved for
  int mask_pixels = 0;             // pixels inside the mask
  nlohmann::json previews;         // file name -> its mapping (previews.h), when usable
  double total_ms = 0.0;

  bool usable() const { return summary.IsSolutionUsable(); }
};

// report.json, the stored form of a result ("termination" is the solver's
// termination name, solvers::core::TerminationName; the measured parts appear only when present).
nlohmann::json ToJson(const PhotometricStereoResult& result);

// A solve's arrays in memory: what SolveAndWrite writes as files.
struct PhotometricStereoMaps {
  solvers::ps::NormalMap map;  // normals, (mono) albedo, flags, model, confidence, specular
  cv::Mat albedo_rgb;          // colour data: CV_32FC3 (R, G, B) albedo with the normals fixed; else empty
  cv::Mat depth;               // CV_32F integrated depth; empty unless integrated
  std::optional<solvers::camera::PixelRays> rays;  // a pinhole camera's, which depth was integrated along
  cv::Mat angular_error_deg;   // CV_32F against ground-truth normals; empty without them
};

// The solve of SolveAndWrite without the files (the Python module's): the
// result lacks only previews and total_ms. Throws std::invalid_argument for a
// request that fails IsValid.
PhotometricStereoResult SolveToMaps(const PhotometricStereoInput& input, const config::PhotometricStereoRequest& request,
                                    PhotometricStereoMaps* maps);

// Solves and writes every output into `output_directory`, report.json last.
// A solver that cannot produce a result is not an exception: the result says
// so (usable() false, summary.message the reason) and is written all the same.
// The folder appears whole, replacing the previous result in one rename
// (results_folder.h); `before_commit`, when given, runs just before that
// rename (it may throw to leave the previous result in place).
PhotometricStereoResult SolveAndWrite(const PhotometricStereoInput& input, const config::PhotometricStereoRequest& request,
                                      const std::string& output_directory,
                                      const std::function<void()>& before_commit = {});

inline PhotometricStereoResult SolvePhotometricStereoRun(const std::string& run_directory,
                                                         const config::PhotometricStereoRequest& request,
                                                         const std::string& output_directory,
                                                         const ColorStackOptions& color = {}) {
  return SolveAndWrite(LoadRunStack(run_directory, color), request, output_directory);
}

// CIEDE2000 of a linear-sRGB albedo against the truth over the pixels where
// `solved` (CV_8U) is non-zero, and over the interior of each paint.
PhotometricStereoResult::ColorErrors CompareColorAlbedo(const cv::Mat& albedo_rgb, const cv::Mat& truth_rgb,
                                                        const cv::Mat& solved);

// CIEDE2000 between two linear-sRGB colours (CIELAB of D65, white Y = 1).
double Ciede2000OfLinearSrgb(const Eigen::Vector3d& a, const Eigen::Vector3d& b);

}  // namespace photorig::daemon
