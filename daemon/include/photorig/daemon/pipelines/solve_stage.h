#pragma once
// A run's solve stages behind one interface: each solves from the stored
// frames, keeps its result and reports it in the daemon's words (the run
// record, its events, `photorig watch`, a Slurm task's follow-up).

#include "photorig/daemon/pipelines/brdf_solve.h"
#include "photorig/daemon/pipelines/led_positions.h"
#include "photorig/daemon/pipelines/light_calibration.h"
#include "photorig/daemon/pipelines/ps_pipeline.h"
#include "photorig/daemon/pipelines/svbrdf_pipeline.h"
#include "photorig/daemon/pipelines/tomography_pipeline.h"
#include "photorig/config/recipe.h"
#include "photorig/solvers/core/names.h"
#include "photorig/solvers/core/progress.h"

#include <nlohmann/json.hpp>

#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace photorig::daemon {

// The solve stages a recipe may end with, by their recipe keys.
enum class SolveStageKind { kPhotometricStereo, kLightCalibration, kLedPositions, kTomography, kSvbrdf, kBrdf };
inline constexpr solvers::core::NameTable<SolveStageKind, 6> kSolveStageNames = {
    {{SolveStageKind::kPhotometricStereo, "photometric_stereo"},
     {SolveStageKind::kLightCalibration, "light_calibration"},
     {SolveStageKind::kLedPositions, "led_positions"},
     {SolveStageKind::kTomography, "tomography"},
     {SolveStageKind::kSvbrdf, "svbrdf"},
     {SolveStageKind::kBrdf, "brdf"}}};
inline const char* SolveStageName(SolveStageKind kind) { return solvers::core::NameOf(kSolveStageNames, kind); }

// What one solve stage of a run produced, in the words the daemon's run
// record, its events and `photorig watch` use.
struct SolveStageReport {
  std::string stage;        // SolveStageName
  bool usable = false;      // the stage's result can be used (PS: IsSolutionUsable; lights: success)
  std::string termination;  // solvers::core::TerminationName; "success" | "failure" for light calibration
  std::string message;
  std::string results;      // the stage's output folder, relative to the run directory: "results/ps"
  nlohmann::json figures;   // key figures: pixels solved, lights, errors against ground truth, ...
  nlohmann::json timings_ms;  // {"total": ...} and, where the solver reports them, "setup" and "solve"

  nlohmann::json ToJson() const;
};

// A photometric-stereo stage's report from its stored report.json (ToJson's
// fields): a solve that ran in another process, e.g. a Slurm task
// (service/internal/slurm_solve.h).
SolveStageReport ReportPhotometricStereoStage(const nlohmann::json& report, bool usable);

// The results of a run's solve stages, each present once its stage has run.
struct SolveResults {
  std::optional<PhotometricStereoResult> photometric_stereo;  // stored as results/ps/report.json
  std::optional<LightCalibrationSummary> light_calibration;   // stored in results/lights
  std::optional<LedPositionCalibration> led_positions;        // stored in results/leds
  std::optional<TomographyResult> tomography;                 // stored in results/tomography
  std::optional<SvbrdfResult> svbrdf;                         // stored in results/svbrdf
  std::optional<BrdfSolveResult> brdf;                        // stored in results/brdf
};

// What a stage reads besides its request: the run's stored frames.
struct StageContext {
  std::string run_directory;
  std::string rig_path;                      // the run's rig (light and LED calibrations copy it)
  solvers::core::ProgressCallback progress;  // the solver's progress, for stages that report it
};

// One solve stage of a recipe: solves from the run's stored frames into
// results/<folder>/ and keeps its result. Run throws ResultsWriteError when
// the results cannot be written; a solver's failure is in the report.
class SolveStage {
 public:
  using RunFunction = std::function<SolveStageReport(const StageContext&, SolveResults*)>;
  SolveStage(SolveStageKind kind, const char* command, RunFunction run)
      : kind_(kind), command_(command), run_(std::move(run)) {}
  SolveStageKind kind() const { return kind_; }
  const char* name() const { return SolveStageName(kind_); }
  // `photorig <command> --run DIR` repeats the stage from the frames.
  const char* command() const { return command_; }
  SolveStageReport Run(const StageContext& context, SolveResults* results) const { return run_(context, results); }

 private:
  SolveStageKind kind_;
  const char* command_;
  RunFunction run_;
};

// The stages `recipe` asks for, in the order they run.
std::vector<SolveStage> StagesOf(const config::Recipe& recipe);

}  // namespace photorig::daemon
