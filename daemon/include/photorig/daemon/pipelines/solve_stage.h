#pragma once
// A solve stage's outcome in the daemon's words: what the run record, its
// events, `photorig watch` and a Slurm task's follow-up report.

#include "photorig/daemon/pipelines/brdf_solve.h"
#include "photorig/daemon/pipelines/light_calibration.h"
#include "photorig/daemon/pipelines/ps_pipeline.h"
#include "photorig/daemon/pipelines/svbrdf_pipeline.h"
#include "photorig/daemon/pipelines/tomography_pipeline.h"

#include <nlohmann/json.hpp>

#include <string>

namespace photorig::daemon {

// What one solve stage of a run produced, in the words the daemon's run
// record, its events and `photorig watch` use.
struct SolveStageReport {
  std::string stage;        // the recipe's key: "photometric_stereo" | "light_calibration" | "tomography"
  bool usable = false;      // the stage's result can be used (PS: IsSolutionUsable; lights: success)
  std::string termination;  // solvers::core::TerminationName for PS; "success" | "failure" for light calibration
  std::string message;
  std::string results;      // the stage's output folder, relative to the run directory: "results/ps"
  nlohmann::json figures;   // key figures: pixels solved, lights, errors against ground truth, ...
  nlohmann::json timings_ms;  // {"total": ...} and, where the solver reports them, "setup" and "solve"

  nlohmann::json ToJson() const;
};

SolveStageReport ReportSolveStage(const PhotometricStereoResult& result);
// The same from a stored report (report.json, ToJson's fields): a solve that
// ran in another process, e.g. a Slurm task (service/internal/slurm_solve.h).
SolveStageReport ReportPhotometricStereoStage(const nlohmann::json& report, bool usable);
SolveStageReport ReportSolveStage(const LightCalibrationSummary& summary, const std::string& run_directory,
                                  double total_ms);
// Usable only when trusted (TomographyResult::trusted).
SolveStageReport ReportSolveStage(const TomographyResult& result);
SolveStageReport ReportSolveStage(const SvbrdfResult& result);
SolveStageReport ReportSolveStage(const BrdfSolveResult& result);

}  // namespace photorig::daemon
