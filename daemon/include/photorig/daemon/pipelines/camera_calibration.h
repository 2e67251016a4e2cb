#pragma once
// Lens calibration of a dome's camera from checkerboard photographs
// (solvers/camera/calibration.h), written as a new rig file: the base rig
// with a pinhole camera and a `calibration:` record of where the lens came
// from. Used by `photorig calibrate camera`.

#include "photorig/solvers/camera/calibration.h"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace photorig::daemon {

struct CameraCalibrationRequest {
  std::vector<std::string> images;  // checkerboard photographs, any order
  solvers::camera::CheckerboardCalibrationOptions options;  // options.plane_image indexes `images`
  std::string base_rig;  // the rig whose camera took the images
  std::string out_rig;   // the new rig; must not exist
};

struct CameraCalibrationResult {
  solvers::camera::CheckerboardCalibrationSummary summary;
  bool rig_written = false;  // true once out_rig holds the calibrated lens and loads as a rig
};

// Reads the images, calibrates the lens and, when the fit is usable, writes
// the new rig and loads it back. Throws std::invalid_argument when an image
// cannot be read, the images' size is not the base rig's frame or out_rig
// exists; config::ConfigError for a bad base rig; std::runtime_error when
// out_rig cannot be written. A calibration that fails is in the summary, and
// no rig is written.
CameraCalibrationResult CalibrateCamera(const CameraCalibrationRequest& request);

// The calibration's figures as `photorig calibrate camera --json` prints them
// (and the Python module returns them): the summary's termination, message
// and timings, the lens and its deviations, the fit's figures, the images
// used and rejected, the distortion model with every candidate, and
// `out_rig` (empty when none was written).
nlohmann::json ToJson(const CameraCalibrationResult& result, const CameraCalibrationRequest& request);

}  // namespace photorig::daemon
