#pragma once
// A whole run, in-process: load rig and recipe, capture every step on the
// rig's devices into a run directory, then run the recipe's solvers on it.
// Shared by the `photorig` CLI and the `photorigd` daemon.

#include "photorig/daemon/pipelines/nexus_export.h"
#include "photorig/daemon/pipelines/solve_stage.h"
#include "photorig/daemon/service/run_request.h"

#include <nlohmann/json.hpp>

#include <atomic>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace photorig::daemon {

// A run: its capture, then the results of its solve stages (SolveResults).
struct RunOutcome : SolveResults {
  std::string directory;
  RecoveryReport recovery;  // when resumed
  CaptureReport capture;
  // An adaptive pose plan's passes after the coarse one, as planned (also in
  // the run directory's adaptive_passes.json); empty without one.
  std::vector<AdaptivePassReport> adaptive_passes;
  std::vector<SolveStageReport> solve_stages;  // in the order they ran
  std::optional<NexusExportSummary> nexus;     // when asked for: RUN/run.nxs
};

// {"status", "reason", "frames_written", "steps_total", "retries",
// "dropped_frames", "elapsed_ms"}: the capture as `photorig run --json` and
// the Python module report it.
nlohmann::json ToJson(const CaptureReport& capture);

// What a run's manifest takes from the rig: camera geometry and response,
// mosaic and colour model, saturation, lamps, reference target.
RunManifest ManifestHeaderFor(const config::RigConfig& rig);

// Throws ConfigError for bad configuration and std::invalid_argument for an
// output directory that already holds files (both before any device is
// touched), std::runtime_error for storage failures or too little free space
// for the run's estimate; device faults end up in outcome.capture.status.
RunOutcome ExecuteRun(const RunRequest& request);

}  // namespace photorig::daemon
