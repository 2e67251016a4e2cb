#pragma once
// Light calibration of a dome from images of a mirror sphere, one per LED:
// the sphere located (a given circle, a silhouette image, or the highlights
// themselves under the rig's nominal directions), each LED's direction from
// its highlight, optional relative RGB intensities from a white sphere, and
// the results as lights.lp, DiLiGenT's light_directions.txt /
// light_intensities.txt, report.json and a new rig YAML (an existing file is
// never overwritten). Used by the recipe stage `light_calibration:` and by
// `photorig calibrate lights`.

#include "photorig/config/recipe.h"
#include "photorig/config/solve_requests.h"
#include "photorig/solvers/camera/camera.h"
#include "photorig/solvers/core/names.h"
#include "photorig/solvers/lighting/light_intensity.h"
#include "photorig/solvers/lighting/mirror_sphere.h"

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include <optional>
#include <string>
#include <vector>

namespace photorig::daemon {

struct LightCalibrationInputs {
  std::vector<cv::Mat> frames;  // mirror sphere, one single-channel frame per LED (empty Mat: no frame)
  std::vector<std::string> names;
  std::vector<Eigen::Vector3d> nominal_directions;  // the rig's, for the highlight fit; may be empty otherwise
  std::vector<cv::Mat> white_frames;                // white sphere, one per LED, optional
  double pixel_pitch_mm = 0.0;                      // object-space pixel size (orthographic); 0 = unknown
  // The run's or rig's camera: a pinhole one's lens locates the sphere unless
  // the command line gives intrinsics of its own.
  solvers::camera::Projection projection = solvers::camera::Projection::kOrthographic;
  solvers::camera::PinholeLens pinhole;
};

// The light frames of a run: one per LED, in LED order, with the rig's
// nominal directions and pixel pitch from the manifest.
LightCalibrationInputs LoadLightCalibrationInputs(const std::string& run_directory);

// White-sphere images, one per light, read as they are (grey or B, G, R, any
// depth) into inputs->white_frames. Throws std::invalid_argument naming an
// image that cannot be read.
void LoadWhiteFrames(const std::vector<std::string>& paths, LightCalibrationInputs* inputs);

// The camera the sphere is located with: `given` when it is a pinhole (fy 0:
// fx), else the inputs' own lens when theirs is a pinhole, else orthographic.
// Throws std::invalid_argument for an own lens with distortion, which the
// sphere fit does not model.
solvers::lighting::CameraModel SphereCamera(const LightCalibrationInputs& inputs, solvers::lighting::CameraModel given);

// How the sphere was located (kNone: not yet, or not at all).
enum class SphereSource { kNone, kCircle, kSilhouette, kHighlights };
inline constexpr solvers::core::NameTable<SphereSource, 4> kSphereSourceNames = {
    {{SphereSource::kNone, "none"},
     {SphereSource::kCircle, "circle"},
     {SphereSource::kSilhouette, "silhouette"},
     {SphereSource::kHighlights, "highlights"}}};
inline const char* SphereSourceName(SphereSource source) { return solvers::core::NameOf(kSphereSourceNames, source); }

struct LightCalibrationSummary {
  bool success = false;  // every light's direction and intensity usable, and all outputs written
  std::string message;
  solvers::lighting::Circle circle;
  SphereSource sphere_source = SphereSource::kNone;
  double sphere_fit_rms_px = 0.0;
  int lights = 0;
  int unusable = 0;  // lights without a usable direction
  // Lights whose white-sphere frame gave no usable intensity (0 without
  // white-sphere frames); they keep their previous intensity.
  int unusable_intensities = 0;
  double mean_uncertainty_deg = 0.0;  // includes circle_shift_deg's per-light shifts
  // A given circle only: mean change of the directions had the sphere been
  // placed from the highlights instead (0 when not checked).
  double circle_shift_deg = 0.0;
  std::string out_rig;  // written, or "" when none was asked for
};

// Each light's estimates, as lights.lp, the DiLiGenT files and report.json
// hold them: intensities only when there are white-sphere frames.
struct LightCalibrationEstimates {
  std::vector<solvers::lighting::LightDirectionEstimate> directions;
  std::vector<solvers::lighting::LightIntensityEstimate> intensities;
};

// Never throws for bad data: an unusable light, a sphere that cannot be found
// or an existing out_rig give success = false and a message. Throws only when
// an output cannot be written. `estimates`, when given, receives each light's
// estimates once the sphere is located.
LightCalibrationSummary CalibrateLights(const LightCalibrationInputs& inputs, const config::LightCalibrationRequest& request,
                                        const std::string& out_directory, LightCalibrationEstimates* estimates = nullptr);

// The summary as `photorig calibrate lights --json` and `photorig run` give it.
nlohmann::json ToJson(const LightCalibrationSummary& summary);

}  // namespace photorig::daemon
