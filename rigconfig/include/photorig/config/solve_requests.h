#pragma once
// The solve stages a recipe may ask for (`solve: [photometric_stereo: ...,
// light_calibration: ..., led_positions: ...]`), and the same settings as the command line gives
// them: parsed and checked when the recipe is loaded.

#include "photorig/config/yaml_node.h"
#include "photorig/solvers/lighting/sphere.h"
#include "photorig/solvers/brdf/fit.h"
#include "photorig/solvers/ps/integration.h"
#include "photorig/solvers/ps/photometric_stereo.h"
#include "photorig/solvers/tomography/reconstruct.h"

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace photorig::config {

struct PhotometricStereoRequest {
  solvers::ps::Method method = solvers::ps::Method::kAuto;
  // Samples within this many read-noise sigmas of black (and within 1 DN) are
  // shadows; the read noise comes from dark frames, or is estimated without them.
  double shadow_threshold_sigma = 3.0;
  double max_condition_number = 1e3;
  // Blinn-Phong fit: lanes (closed-form derivatives, sixteen pixels per SIMD
  // pass in float) | forward | reverse | symbolic | central-difference (one pixel at a
  // time, Jacobians by that method).
  solvers::ps::BlinnPhongDerivative derivative = solvers::ps::BlinnPhongDerivative::kLanes;
  // A rig that gives its LEDs' positions is solved with the near-light model
  // (l2 and lambertian; solvers/ps/near_lights.h). With assume_distant, or a
  // method that fits one light matrix for all pixels, it is solved as if the
  // LEDs were distant, and refused when the geometry predicts that model's
  // bias above max_distant_bias_deg (the error budget of a good solve).
  bool assume_distant = false;
  double max_distant_bias_deg = 0.5;
  // Depth from the normals by this integrator; nullopt: none (normals only).
  std::optional<solvers::ps::Integrator> integrator = solvers::ps::Integrator::kPoisson;
  // Masked pixels left without a normal (too few usable samples, a rejected
  // fit) get one interpolated from their solved neighbours, flagged `filled`
  // (solvers/ps/fill_unresolved.h), so depth and meshes have no holes.
  bool fill_unresolved = true;
  // Not from YAML: whoever runs the solve listens here (the CLI's progress bar).
  solvers::core::ProgressCallback progress;

  bool IsValid(std::string* why) const;
};

// Throws ConfigError naming file:line:column for unknown keys or values.
PhotometricStereoRequest ParsePhotometricStereoRequest(const YamlNode& node);

// The integrator as requests name it: an IntegratorName, or "none".
inline constexpr const char* kNoIntegrator = "none";
// Sets *integrator from `name` (nullopt for "none"); false for other text.
bool ParseIntegratorChoice(std::string_view name, std::optional<solvers::ps::Integrator>* integrator);
const char* IntegratorChoiceName(const std::optional<solvers::ps::Integrator>& integrator);
std::vector<std::string> IntegratorChoices();  // poisson, frankot-chellappa, none

struct LightCalibrationRequest {
  // How the sphere is found, in this order of preference: a given circle, a
  // silhouette image, else the highlights (see LocateSphereFromHighlights).
  std::optional<solvers::lighting::Circle> circle;
  std::string silhouette_image;
  double sphere_radius_mm = 0.0;  // > 0 with a known pixel pitch fixes the radius of the highlight fit
  solvers::lighting::CameraModel camera;   // orthographic unless pinhole intrinsics are given
  std::string base_rig;           // rig YAML to copy with the calibrated lights ("" = no rig output)
  std::string out_rig;            // the new rig YAML; must not exist

  bool IsValid(std::string* why) const;
};

// The recipe stage `light_calibration: {sphere: {circle: [cx, cy, r]} |
// {silhouette: IMAGE} | {from: highlights, radius_mm: R}, out_rig: FILE}`;
// paths are relative to the recipe. Throws ConfigError naming file:line:column.
LightCalibrationRequest ParseLightCalibrationRequest(const YamlNode& node);

// The recipe stage `led_positions: {spheres: [[x, y], [x, y, z], ...],
// radius_mm: R, out_rig: FILE}` and `photorig calibrate leds`'s flags: a
// near-LED dome's LED positions from two or more mirror spheres at known
// places (solvers/lighting/led_positions.h). Paths are relative to the
// recipe. Throws ConfigError naming file:line:column.
struct LedPositionRequest {
  // Dome frame, mm; z (default 0) is the centre's height above the sample
  // plane: 0 for the simulator's balls, whose equator lies on it, the radius
  // for a ball resting on it.
  std::vector<Eigen::Vector3d> sphere_centres_mm;
  double sphere_radius_mm = 0.0;
  std::string base_rig;  // rig YAML to copy with the calibrated positions ("" = no rig output)
  std::string out_rig;   // the new rig YAML; must not exist

  bool IsValid(std::string* why) const;
};
LedPositionRequest ParseLedPositionRequest(const YamlNode& node);

// The recipe stage `tomography: {method, projector, max_iterations,
// discrepancy_factor, volume: [nx, ny, nz], voxel_mm, cor_offset_mm,
// ring_filter, held_out}` and
// `photorig solve tomography`'s flags: a turntable scan's frames -> absorbance
// -> a reconstructed volume (solvers/tomography, docs/tomography.md).
struct TomographyRequest {
  // sirt (default: the docs' choice for a scan of many views, stopped by the
  // discrepancy rule) | art | cgls | sart.
  solvers::tomography::Method method = solvers::tomography::Method::kSirt;
  // SART's total-variation regularisation (docs/tomography.md): for samples
  // known to be piecewise constant. Off by default: the data do not say so.
  bool total_variation = false;
  // joseph (default: the lower error) | siddon
  solvers::tomography::Interpolation projector = solvers::tomography::Interpolation::kJoseph;
  int max_iterations = 300;
  // tau of the discrepancy rule. Default 1.2, not Morozov's 1: a scan's
  // residual keeps the model error of the voxel grid (pixels integrate the
  // sample over their area, edges cut voxels) on top of the noise, and on the
  // simulated tomograph SIRT is still 1.16 x the noise level after 300
  // iterations (docs/tomography.md); the theory asks tau > 1 for that reason.
  double discrepancy_factor = 1.2;
  // Voxels along x, y, z; 0: the detector's columns, columns and rows.
  std::array<int, 3> volume = {0, 0, 0};
  double voxel_mm = 0.0;             // 0: the detector pitch
  // The rotation axis on the detector (solvers::tomography::Geometry), added
  // to the stored geometry's. Unset (default): estimated from the data, since
  // a rig's stored centre is never exact (solvers/tomography/center_of_rotation.h).
  std::optional<double> cor_offset_mm;
  // Removes detector-column stripes (ring artefacts) from the sinogram before
  // the solve (solvers/tomography/ring_filter.h). Off by default.
  bool ring_filter = false;
  // Reports the held-out-angle residual (solvers/tomography/held_out.h), the
  // quality figure without a ground truth: a second solve of half the views.
  bool held_out = true;
  // Not from YAML: whoever runs the solve listens here (the CLI's progress bar).
  solvers::core::ProgressCallback progress;
  // Not from YAML: how messages name max_iterations (the recipe's key; the
  // CLI sets its flag, --max-iterations).
  std::string iteration_limit_name = "max_iterations";

  bool IsValid(std::string* why) const;
};

// Throws ConfigError naming file:line:column for unknown keys or values.
TomographyRequest ParseTomographyRequest(const YamlNode& node);

// The recipe stage `svbrdf: {photometric_stereo: {...}, max_materials,
// held_out_lights, gltf}` and `photorig solve svbrdf`'s flags: normals by
// photometric stereo, then per-pixel albedo and per-material lobes
// (solvers/reflectance, docs/reflectance.md).
struct SvbrdfRequest {
  PhotometricStereoRequest ps;   // how the normals are solved
  int max_materials = 4;         // ReflectanceOptions::max_materials
  int held_out_lights = 8;       // RelightingOptions::held_out_lights (0 = every light); -1 = skip the check
  bool export_gltf = true;
  // Refine the normals with the materials' lobes, alternating with the
  // reflectance fit (RefineNormalsAndReflectance). Default off.
  bool refine_normals = false;
  // Not from YAML: whoever runs the solve listens here (the CLI's progress bar).
  solvers::core::ProgressCallback progress;

  // The photometric-stereo request, max_materials as ReflectanceOptions
  // takes it, held_out_lights >= -1; the YAML reader, the CLI and the
  // Python module refuse a request with this one message.
  bool IsValid(std::string* why) const;
};

// Throws ConfigError naming file:line:column for unknown keys or values.
SvbrdfRequest ParseSvbrdfRequest(const YamlNode& node);

// The recipe stage `brdf: {loss, calibration}` and `photorig solve brdf`'s
// flags: a gonioreflectometer run's frames -> calibrated BRDF samples -> every
// candidate model fitted and the one the data support chosen
// (docs/brdf-measurement.md, docs/brdf.md).
struct BrdfRequest {
  // weighted: each sample by its propagated deviation; log: Löw et al.'s log
  // loss, for samples without deviations.
  solvers::brdf::FitLoss loss = solvers::brdf::FitLoss::kWeighted;
  // The radiometric scale from the run's reference-target frames; false: from
  // the camera's stated response.
  bool calibrate_with_target = true;
  static constexpr solvers::core::NameTable<bool, 2> kCalibrationNames = {{{true, "reference"}, {false, "camera"}}};
  // Not from YAML: whoever runs the solve listens here.
  solvers::core::ProgressCallback progress;
};

// Throws ConfigError naming file:line:column for unknown keys or values.
BrdfRequest ParseBrdfRequest(const YamlNode& node);

}  // namespace photorig::config
