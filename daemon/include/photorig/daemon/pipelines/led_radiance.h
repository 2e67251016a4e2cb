#pragma once
// Each near LED's intensity and radiance profile from a run that photographed
// a matte plane of known albedo under every LED in turn
// (solvers/lighting/led_radiance.h), written as results and as a new rig file
// whose LEDs carry them. Used by `photorig calibrate radiance`.

#include "photorig/solvers/lighting/led_radiance.h"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace photorig::daemon {

struct LedRadianceRequest {
  std::string run_directory;
  solvers::lighting::LedRadianceOptions options;
  // The rig to start from: its LED positions and camera replace the run's
  // for the fit (ApplyRigCalibration), and the new rig is its copy. "": the run's.
  std::string base_rig;
  std::string out_rig;           // the new rig; "" = none; must not exist
  std::string output_directory;  // "" = RUN/results/led-radiance
};

struct LedRadianceResult {
  solvers::lighting::LedRadianceSummary summary;
  std::vector<int> led_ids;          // the rig's id of each estimate
  std::vector<double> stated_intensity;  // the rig's, for comparison
  std::string output_directory;
  bool rig_written = false;  // only when every LED was usable
};

// Throws std::invalid_argument when the run is not one frame of the plane
// per LED of a rig with LED positions and dark frames, or out_rig exists;
// std::runtime_error when the results cannot be written. A calibration the
// data do not support is in the summary, with no rig written.
LedRadianceResult CalibrateLedRadianceRun(const LedRadianceRequest& request);

// The calibration as report.json holds it: the request's settings, the
// summary and one entry per LED (the rig's stated intensity beside the fit).
nlohmann::json ToJson(const LedRadianceRequest& request, const LedRadianceResult& result);

}  // namespace photorig::daemon
