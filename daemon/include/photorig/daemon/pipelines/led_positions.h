#pragma once
// LED positions of a near-LED dome from a run of mirror-sphere frames, one per
// LED, with two or more balls at known places (solvers/lighting/led_positions.h):
// report.json (each LED's position, its shift from the rig's nominal one, the
// rays' residual and flags) and a new rig YAML with the positions and a record
// of the calibration (an existing file is never overwritten). Used by the
// recipe stage `led_positions:` and by `photorig calibrate leds`.

#include "photorig/config/rig.h"
#include "photorig/config/solve_requests.h"
#include "photorig/solvers/camera/camera.h"
#include "photorig/solvers/lighting/led_positions.h"

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace photorig::daemon {

struct LedPositionInputs {
  std::vector<cv::Mat> frames;  // one single-channel frame per LED, in LED order (empty Mat: none captured)
  std::vector<std::string> names;
  std::vector<config::LedConfig> leds;  // the rig's, as the run recorded them (nominal positions)
  solvers::camera::Camera camera;
  std::string run_directory;
  // Near LEDs as simulated (ground_truth/light_positions.txt); empty for a real run.
  std::vector<Eigen::Vector3d> true_positions_mm;
};

// The LED frames of a run, its camera and the rig's LEDs from its manifest.
LedPositionInputs LoadLedPositionInputs(const std::string& run_directory);

struct LedPositionCalibration {
  bool success = false;     // every LED placed and all outputs written
  bool bad_input = false;   // the request or the run cannot give positions at all (nothing solved)
  std::string message;
  solvers::lighting::LedPositionSummary solve;
  double mean_shift_mm = 0.0;  // placed LEDs' distance from the rig's nominal positions
  double max_shift_mm = 0.0;
  double max_rms_ray_distance_mm = 0.0;
  // Against the simulator's truth, when the run has it (else negative).
  double mean_error_mm = -1.0;
  double max_error_mm = -1.0;
  std::string out_rig;  // written, or "" (none asked for, or an LED unusable)
};

// Never throws for bad data: an unusable LED gives success = false and no rig;
// a bad request or run gives bad_input. Throws only when an output cannot be written.
LedPositionCalibration CalibrateLedPositions(const LedPositionInputs& inputs, const config::LedPositionRequest& request,
                                             const std::string& out_directory);

// The calibration as `photorig calibrate leds --json` gives it (without `out`).
nlohmann::json ToJson(const LedPositionCalibration& result);

}  // namespace photorig::daemon
