// photorig run RECIPE [--rig FILE] [--out DIR] [--no-solve]

#include "../command.h"
#include "../signals.h"
#include "photorig/daemon/run.h"
#include "ps_report.h"

#include <cstdio>
#include <memory>

namespace photorig::app {
namespace {

struct Options {
  std::string recipe, rig, out;
  bool no_solve = false;
};

int Execute(const Options& options) {
  daemon::RunRequest request;
  request.recipe_path = options.recipe;
  request.rig_path = options.rig;
  request.output_directory = options.out;
  request.solve = !options.no_solve;
  request.show_progress = true;
  request.stop_requested = &g_stop_requested;
  const daemon::RunOutcome outcome = daemon::ExecuteRun(request);
  std::printf("run directory: %s\n", outcome.directory.c_str());
  std::printf("capture: %s, %d/%d frames, %.0f ms%s%s\n", daemon::CaptureStatusName(outcome.capture.status),
              outcome.capture.frames_written, outcome.capture.steps_total, outcome.capture.elapsed_ms,
              outcome.capture.reason.empty() ? "" : ": ", outcome.capture.reason.c_str());
  if (outcome.photometric_stereo) {
    PrintPhotometricStereoSummary(*outcome.photometric_stereo);
    std::printf("results: %s/results/ps/\n", outcome.directory.c_str());
    if (!outcome.photometric_stereo->usable()) return 1;
  }
  if (outcome.light_calibration) {
    const daemon::LightCalibrationSummary& lights = *outcome.light_calibration;
    std::printf("light calibration: %s; sphere at (%.2f, %.2f) px, radius %.2f px; mean uncertainty %.2f deg\n",
                lights.message.c_str(), lights.circle.cx_px, lights.circle.cy_px, lights.circle.radius_px,
                lights.mean_uncertainty_deg);
    if (!lights.out_rig.empty()) std::printf("calibrated rig: %s\n", lights.out_rig.c_str());
    if (!lights.success) return 3;
  }
  if (outcome.capture.status == daemon::CaptureStatus::kAborted) return 130;
  return outcome.capture.status == daemon::CaptureStatus::kComplete ? 0 : 1;
}

CommandRunner Setup(CLI::App& app) {
  auto options = std::make_shared<Options>();
  CLI::App* sub = app.add_subcommand("run", "capture a recipe on its rig and run its solvers (no daemon needed)");
  sub->add_option("recipe", options->recipe, "recipe YAML")->required()->check(CLI::ExistingFile);
  sub->add_option("--rig", options->rig, "rig YAML (default: the rig the recipe names)")->check(CLI::ExistingFile);
  sub->add_option("--out", options->out, "run directory to create (default: runs/<recipe>-<UTC time>)");
  sub->add_flag("--no-solve", options->no_solve, "capture only");
  return {sub, [options] { return Execute(*options); }};
}

const bool registered = RegisterCommand(Setup);

}  // namespace
}  // namespace photorig::app
