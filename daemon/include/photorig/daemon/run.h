#pragma once
// A whole run, in-process: load rig and recipe, capture every step on the
// rig's devices into a run directory, then run the recipe's solvers on it.
// Shared by the `photorig` CLI and the `photorigd` daemon.

#include "photorig/daemon/light_calibration.h"
#include "photorig/daemon/ps_pipeline.h"
#include "photorig/daemon/sequencer.h"

#include <atomic>
#include <functional>
#include <optional>
#include <string>

namespace photorig::daemon {

struct RunRequest {
  std::string recipe_path;
  std::string rig_path;       // empty: the rig the recipe names
  std::string output_directory;  // empty: runs/<recipe>-<UTC timestamp>
  bool solve = true;
  bool show_progress = true;  // a progress line on stderr
  // Reopen the interrupted run in output_directory and capture only the steps
  // it lacks (see RunWriter::Reopen) instead of creating a new run.
  bool resume = false;
  const std::atomic<bool>* stop_requested = nullptr;
  RunControl* control = nullptr;
  RetryPolicy retry;
  // After each stored frame; `frames_in_run` counts resumed frames too.
  std::function<void(const CaptureStep&, const FrameRecord&, int frames_in_run, int total)> on_frame;
  std::function<void(RunState, const std::string& detail)> on_state;
  // Given to the recipe's solvers (solvers/progress.h).
  solvers::ProgressCallback solve_progress;
};

struct RunOutcome {
  std::string directory;
  RecoveryReport recovery;  // when resumed
  CaptureReport capture;
  std::optional<PhotometricStereoResult> photometric_stereo;  // stored as results/ps/report.json
  std::optional<LightCalibrationSummary> light_calibration;
};

// Throws ConfigError for bad configuration (before any device is touched) and
// std::runtime_error for storage failures or too little free space for the
// run's estimate; device faults end up in outcome.capture.status.
RunOutcome ExecuteRun(const RunRequest& request);

}  // namespace photorig::daemon
