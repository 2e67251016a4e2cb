#pragma once
// A gonioreflectometer run -> BRDF samples in 1/sr with deviations.
//
// Every pixel of the orthographic camera sees the sample under the same
// directions, so each pose gives one sample from a central block of pixels:
//   * per pixel and exposure t (at gain g): the mean of the pose's repeats,
//     minus the mean dark frame taken at that same exposure, divided by t g: a
//     rate in DN per us at 0 dB. Exposures whose repeats clip the pixel are
//     left out; the rest are combined with inverse-variance weights from the
//     sensor's noise model,
//       var(DN) = read_sigma^2 + (g / e_per_dn) S        (S: signal above black, DN)
//     evaluated at the pixel's best rate (so a low reading does not weigh more
//     for being low), plus the dark mean's own variance;
//   * the block's rate is the mean of its pixels' rates, its variance the sum
//     of theirs over the pixel count squared; a colour camera's (a Bayer
//     mosaic's) per channel, over that channel's own sites in the block (the
//     sample fills the block uniformly: no demosaicing);
//   * f_r = rate / (K E level cos theta_i), with K the DN per unit radiance
//     per us at 0 dB and E the lamp's irradiance at normal incidence. K comes
//     from the reference target's frames (a Lambertian standard of albedo rho:
//     K E = rate_target pi / (rho level_target cos theta_i,target), so the
//     lamp's stated irradiance cancels), or, when asked, from the camera's
//     stated response. K is per camera channel: the grey target gives each
//     channel its own, so the channels' gains cancel and f_r is in 1/sr per
//     camera channel.
// The read noise is measured from the dark frames' temporal spread (two or
// more darks at one exposure); the shot term from the camera's e_per_dn, or,
// where the rig does not state it, from the spread of the pose repeats.

#include "photorig/daemon/capture/run_store.h"
#include "photorig/solvers/brdf/samples.h"
#include "photorig/solvers/core/names.h"
#include "photorig/solvers/core/summary.h"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace photorig::daemon {

struct BrdfMeasurementOptions {
  enum class Calibration {
    kReferenceTarget,  // K from the run's reference-target frames (default)
    kCameraResponse,   // K = the camera's stated dn_per_radiance_per_us, no target needed
  };
  static constexpr solvers::core::NameTable<Calibration, 2> kCalibrationNames = {
      {{Calibration::kReferenceTarget, "reference_target"}, {Calibration::kCameraResponse, "camera_response"}}};
  Calibration calibration = Calibration::kReferenceTarget;
  // Side of the central block of pixels averaged into a sample. 8 stays on a
  // 12 mm sample seen through 0.5 mm pixels up to a camera arm at 80 deg.
  int block_px = 8;
  // The reference target's merged rate must be known to this relative
  // deviation; a target darker than that is refused, not used.
  double max_target_relative_sigma = 0.01;
  // A pose whose block clips at every exposure, this close (theta_h, deg) to
  // the specular peak, means the peak itself was clipped.
  double peak_theta_h_deg = 5.0;

  bool IsValid(std::string* why) const;
};

// One pose whose block clipped at every exposure it was taken at: no sample.
struct ClippedPose {
  config::GonioPose pose;
  double theta_h_deg = 0.0;
  double shortest_exposure_us = 0.0;
};

struct BrdfMeasurement : solvers::core::Summary {
  std::vector<solvers::brdf::BrdfSample> samples;  // one per usable pose, in capture order, each with its origin
  int pose_frames = 0, dark_frames = 0, target_frames = 0;
  int poses = 0;
  int bracketed_poses = 0;  // poses taken at more than one exposure
  std::vector<ClippedPose> clipped;
  int below_horizon = 0;
  bool peak_clipped = false;  // a clipped pose lies within peak_theta_h_deg of the peak

  // The noise model the deviations come from (DN at 0 dB).
  double read_sigma_dn = 0.0;  // measured from the darks' temporal spread
  double shot_dn_per_dn = 0.0;  // variance per DN of signal: 1 / e_per_dn
  bool shot_estimated = false;  // from the repeats (the rig states no e_per_dn)
  // The propagated deviation against the repeats' spread: sqrt of the pooled
  // ratio of each pose's sample variance over repeats to its propagated
  // variance, for a single frame's block mean (1 for an honest noise model;
  // its own spread about sqrt(1 / (2 dof))); dof = 0 without repeats.
  double repeat_sigma_ratio = 0.0;
  int repeat_dof = 0;

  // The radiometric scale.
  BrdfMeasurementOptions::Calibration calibration = BrdfMeasurementOptions::Calibration::kReferenceTarget;
  double dn_per_radiance_per_us = 0.0;  // K as applied (with E: the lamp's stated irradiance)
  double calibration_relative_sigma = 0.0;  // shared by every sample (0: not known)
  double reference_albedo = 0.0;
  double camera_dn_per_radiance_per_us = 0.0;  // what the camera states, for comparison

  // The camera's colour filter as stored ("mono" or a Bayer pattern, e.g.
  // "RGGB"). K and its relative deviation per channel (R, G, B), and the
  // block's sites of each; a grey camera's three channels are equal (all 64
  // sites count as channel R's). The scalars above are then a grey camera's
  // K, or a colour camera's green K and its worst channel's deviation.
  std::string mosaic = "mono";
  Eigen::Vector3d channel_dn_per_radiance_per_us = Eigen::Vector3d::Zero();
  Eigen::Vector3d channel_calibration_relative_sigma = Eigen::Vector3d::Zero();
  Eigen::Vector3i channel_sites = Eigen::Vector3i::Zero();
  // The rig's colour model (camera.color_model) when the run was captured,
  // and what was done with it: a linear (3 x 3) model converts the samples to
  // linear sRGB (camera_to_linear_srgb, applied to f_r per camera channel);
  // any other is not applied, and the note says why. Empty for a grey camera
  // or a rig without one.
  std::string color_model_path;
  std::string color_model_kind;  // e.g. "root-poly-2", "linear"
  bool color_model_applied = false;
  std::string color_model_note;
  Eigen::Matrix3d camera_to_linear_srgb = Eigen::Matrix3d::Identity();
};

// Reads the run's frames. Ends kInvalidInput when the run lacks what the
// measurement needs (dark frames at a pose's exposure, two darks at one
// exposure, a reference target when calibrating against one, a grey camera
// or a Bayer mosaic) and kFailure when the reference target is saturated at every
// exposure or too dark; the message says which and what to do.
BrdfMeasurement MeasureBrdf(const std::string& run_dir, const RunManifest& manifest,
                            const BrdfMeasurementOptions& options = {});

}  // namespace photorig::daemon
