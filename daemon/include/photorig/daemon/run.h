#pragma once
// A whole run, in-process: load rig and recipe, capture every step on the
// rig's devices into a run directory, then run the recipe's solvers on it.
// Shared by the `photorig` CLI and the `photorigd` daemon.

#include "photorig/daemon/adaptive_poses.h"
#include "photorig/daemon/brdf_solve.h"
#include "photorig/daemon/light_calibration.h"
#include "photorig/daemon/ps_pipeline.h"
#include "photorig/daemon/sequencer.h"
#include "photorig/daemon/svbrdf_pipeline.h"
#include "photorig/daemon/tomography_pipeline.h"

#include <nlohmann/json.hpp>

#include <atomic>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace photorig::daemon {

// What one solve stage of a run produced, in the words the daemon's run
// record, its events and `photorig watch` use.
struct SolveStageReport {
  std::string stage;        // the recipe's key: "photometric_stereo" | "light_calibration" | "tomography"
  bool usable = false;      // the stage's result can be used (PS: IsSolutionUsable; lights: success)
  std::string termination;  // solvers::TerminationName for PS; "success" | "failure" for light calibration
  std::string message;
  std::string results;      // the stage's output folder, relative to the run directory: "results/ps"
  nlohmann::json figures;   // key figures: pixels solved, lights, errors against ground truth, ...
  nlohmann::json timings_ms;  // {"total": ...} and, where the solver reports them, "setup" and "solve"

  nlohmann::json ToJson() const;
};

SolveStageReport ReportSolveStage(const PhotometricStereoResult& result);
// The same from a stored report (report.json, ToJson's fields): a solve that
// ran in another process, e.g. a Slurm task (slurm_solve.h).
SolveStageReport ReportPhotometricStereoStage(const nlohmann::json& report, bool usable);
SolveStageReport ReportSolveStage(const LightCalibrationSummary& summary, const std::string& run_directory,
                                  double total_ms);
// Usable only when trusted (TomographyResult::trusted).
SolveStageReport ReportSolveStage(const TomographyResult& result);
SolveStageReport ReportSolveStage(const SvbrdfResult& result);
SolveStageReport ReportSolveStage(const BrdfSolveResult& result);

struct RunRequest {
  std::string recipe_path;
  std::string rig_path;       // empty: the rig the recipe names
  std::string output_directory;  // empty: runs/<recipe>-<UTC timestamp>
  bool solve = true;
  // Reopen the interrupted run in output_directory and capture only the steps
  // it lacks (see RunWriter::Reopen) instead of creating a new run.
  bool resume = false;
  const std::atomic<bool>* stop_requested = nullptr;
  RunControl* control = nullptr;
  RetryPolicy retry;
  // After each stored frame; `frames_in_run` counts resumed frames too.
  std::function<void(const CaptureStep&, const FrameRecord&, int frames_in_run, int total)> on_frame;
  std::function<void(RunState, const std::string& detail)> on_state;
  // After each pass of an adaptive pose plan is planned (on_state hears its detail too).
  std::function<void(const AdaptivePassReport&)> on_adaptive_pass;
  // Around each solve stage after a complete capture; on_state hears
  // kSolving (detail: the stage) before the first. An abort requested through
  // `control` while a stage runs skips the stages after it.
  std::function<void(const std::string& stage)> on_solve_started;
  std::function<void(const SolveStageReport&)> on_solve_finished;
  // A stage handed to Slurm (the recipe's or the rig's solve executor): its job ("JOB_TASK")
  // and batch folder, when submitted or, after a restart, followed again.
  std::function<void(const std::string& stage, const std::string& job_id, const std::string& batch)>
      on_solve_submitted;
  // Given to the recipe's solvers (solvers/progress.h).
  solvers::ProgressCallback solve_progress;
};

struct RunOutcome {
  std::string directory;
  RecoveryReport recovery;  // when resumed
  CaptureReport capture;
  // An adaptive pose plan's passes after the coarse one, as planned (also in
  // the run directory's adaptive_passes.json); empty without one.
  std::vector<AdaptivePassReport> adaptive_passes;
  std::optional<PhotometricStereoResult> photometric_stereo;  // stored as results/ps/report.json
  std::optional<LightCalibrationSummary> light_calibration;
  std::optional<TomographyResult> tomography;  // stored in results/tomography
  std::optional<SvbrdfResult> svbrdf;          // stored in results/svbrdf
  std::optional<BrdfSolveResult> brdf;         // stored in results/brdf
  std::vector<SolveStageReport> solve_stages;  // in the order they ran
};

// What a run's manifest takes from the rig: camera geometry and response,
// mosaic and colour model, saturation, lamps, reference target.
RunManifest ManifestHeaderFor(const RigConfig& rig);

// Throws ConfigError for bad configuration and std::invalid_argument for an
// output directory that already holds files (both before any device is
// touched), std::runtime_error for storage failures or too little free space
// for the run's estimate; device faults end up in outcome.capture.status.
RunOutcome ExecuteRun(const RunRequest& request);

}  // namespace photorig::daemon
