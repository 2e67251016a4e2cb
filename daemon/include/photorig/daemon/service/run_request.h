#pragma once
// What a run is asked to do, and whom it tells as it goes (service/run.h runs it).

#include "photorig/daemon/capture/run_control.h"
#include "photorig/daemon/capture/run_store.h"
#include "photorig/daemon/capture/sequencer.h"
#include "photorig/daemon/pipelines/adaptive_poses.h"
#include "photorig/daemon/pipelines/solve_stage.h"
#include "photorig/solvers/core/progress.h"

#include <atomic>
#include <functional>
#include <string>

namespace photorig::daemon {

struct RunRequest {
  std::string recipe_path;
  std::string rig_path;       // empty: the rig the recipe names
  std::string output_directory;  // empty: runs/<recipe>-<UTC timestamp>
  bool solve = true;
  // Also write RUN/run.nxs when the capture and its solves end (`run --nexus`;
  // the recipe's `export: {nexus: true}` asks for it too).
  bool nexus = false;
  // Reopen the interrupted run in output_directory and capture only the steps
  // it lacks (see RunWriter::Reopen) instead of creating a new run.
  bool resume = false;
  const std::atomic<bool>* stop_requested = nullptr;
  RunControl* control = nullptr;
  RetryPolicy retry;
  // After each stored frame; `frames_in_run` counts resumed frames too.
  std::function<void(const config::CaptureStep&, const FrameRecord&, int frames_in_run, int total)> on_frame;
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
  solvers::core::ProgressCallback solve_progress;
};

}  // namespace photorig::daemon
