// photorig run RECIPE [--rig FILE] [--out DIR] [--no-solve] [--nexus]

#include "../command.h"
#include "../command_output.h"
#include "../progress_display.h"
#include "../signals.h"
#include "photorig/daemon/pipelines/internal/brdf_report.h"
#include "photorig/daemon/service/run.h"
#include "ps_report.h"

#include <cstdio>

namespace photorig::app {
namespace {

struct Options {
  std::string recipe, rig, out;
  bool no_solve = false;
  bool nexus = false;  // RunRequest::nexus
};

int Execute(const Options& options) {
  ProgressDisplay progress;
  daemon::RunRequest request;
  request.recipe_path = options.recipe;
  request.rig_path = options.rig;
  request.output_directory = options.out;
  request.solve = !options.no_solve;
  request.nexus = options.nexus;
  request.on_frame = [&progress](const config::CaptureStep& step, const daemon::FrameRecord&, int frames, int total) {
    progress.Update("captured", frames, total, step.label);
  };
  request.on_adaptive_pass = [&progress](const daemon::AdaptivePassReport& pass) {
    progress.EndLine();
    std::fprintf(stderr, "adaptive pass %d: %d poses added (%d frames) from %d samples%s%s\n", pass.pass,
                 pass.poses_added, pass.frames_added, pass.samples, pass.stopped.empty() ? "" : "; stopped early: ",
                 pass.stopped.c_str());
  };
  request.solve_progress = progress.Callback();
  request.stop_requested = &g_stop_requested;
  const daemon::RunOutcome outcome = daemon::ExecuteRun(request);
  progress.EndLine();
  ResultFields()["run_directory"] = outcome.directory;
  ResultFields()["capture"] = daemon::ToJson(outcome.capture);
  if (!outcome.adaptive_passes.empty()) {
    nlohmann::json passes = nlohmann::json::array();
    for (const daemon::AdaptivePassReport& pass : outcome.adaptive_passes) {
      passes.push_back(pass.ToJson());
      std::printf("adaptive pass %d: %d poses added%s%s\n", pass.pass, pass.poses_added,
                  pass.stopped.empty() ? "" : "; stopped early: ", pass.stopped.c_str());
    }
    ResultFields()["adaptive_passes"] = passes;
  }
  std::printf("run directory: %s\n", outcome.directory.c_str());
  std::printf("capture: %s, %d/%d frames, %.0f ms%s%s\n", daemon::CaptureStatusName(outcome.capture.status),
              outcome.capture.frames_written, outcome.capture.steps_total, outcome.capture.elapsed_ms,
              outcome.capture.reason.empty() ? "" : ": ", outcome.capture.reason.c_str());
  if (outcome.nexus) {
    for (const std::string& warning : outcome.nexus->warnings) std::fprintf(stderr, "warning: %s\n", warning.c_str());
    ResultFields()["nexus"] = outcome.nexus->ToJson();
    if (!outcome.nexus->IsSolutionUsable()) return Fail(kExitFailed, "the NeXus export failed: " + outcome.nexus->message);
    std::printf("%s\n", outcome.nexus->Line().c_str());
  }
  if (outcome.capture.status == daemon::CaptureStatus::kAborted)
    return Fail(kExitInterrupted, "capture aborted: " + outcome.capture.reason);
  if (outcome.capture.status != daemon::CaptureStatus::kComplete)
    return Fail(outcome.capture.fault == StatusCode::kUnavailable ? kExitUnavailable : kExitFailed,
                "capture " + std::string(daemon::CaptureStatusName(outcome.capture.status)) + ": " +
                    outcome.capture.reason);
  if (outcome.photometric_stereo) {
    PrintPhotometricStereoSummary(*outcome.photometric_stereo);
    ResultFields()["photometric_stereo"] = daemon::ToJson(*outcome.photometric_stereo);
    ReportResultsDirectory(outcome.directory + "/results/ps", ResultFields()["photometric_stereo"]);
    if (!outcome.photometric_stereo->usable())
      return Fail(kExitFailed, "photometric stereo gave no usable result: " +
                                   outcome.photometric_stereo->summary.message);
  }
  if (outcome.light_calibration) {
    const daemon::LightCalibrationSummary& lights = *outcome.light_calibration;
    std::printf("light calibration: %s; sphere at (%.2f, %.2f) px, radius %.2f px; mean uncertainty %.2f deg\n",
                lights.message.c_str(), lights.circle.cx_px, lights.circle.cy_px, lights.circle.radius_px,
                lights.mean_uncertainty_deg);
    if (!lights.out_rig.empty()) std::printf("calibrated rig: %s\n", lights.out_rig.c_str());
    ResultFields()["light_calibration"] = daemon::ToJson(lights);
    if (!lights.success) return Fail(kExitFailed, "light calibration failed: " + lights.message);
  }
  if (outcome.led_positions) {
    const daemon::LedPositionCalibration& leds = *outcome.led_positions;
    std::printf("LED positions: %s; rays meet within %.3f mm RMS on average; LEDs moved %.2f mm on average\n",
                leds.message.c_str(), leds.solve.mean_rms_ray_distance_mm, leds.mean_shift_mm);
    if (!leds.out_rig.empty()) std::printf("calibrated rig: %s\n", leds.out_rig.c_str());
    ResultFields()["led_positions"] = {{"success", leds.success}, {"message", leds.message},
                                       {"unusable", leds.solve.unusable}, {"out_rig", leds.out_rig}};
    if (!leds.success) return Fail(kExitFailed, "LED positions failed: " + leds.message);
  }
  if (outcome.tomography) {
    const daemon::TomographyResult& tomo = *outcome.tomography;
    std::printf("tomography (%s): %s, %d iterations, stopped by %s%s\n", solvers::tomography::MethodName(tomo.reconstruction.method),
                solvers::core::TerminationName(tomo.reconstruction.termination), tomo.reconstruction.iterations,
                solvers::tomography::StopReasonName(tomo.reconstruction.stop_reason),
                tomo.reconstruction.message.empty() ? "" : ("; " + tomo.reconstruction.message).c_str());
    if (tomo.relative_error_vs_truth) std::printf("  vs the phantom: relative L2 error %.3f\n", *tomo.relative_error_vs_truth);
    ResultFields()["tomography"] = tomo.ToJson();
    ReportResultsDirectory(outcome.directory + "/results/tomography", ResultFields()["tomography"]);
    if (!tomo.trusted()) return Fail(kExitFailed, "the tomographic reconstruction cannot be trusted: " + tomo.reconstruction.message);
  }
  if (outcome.svbrdf) {
    const daemon::SvbrdfResult& svbrdf = *outcome.svbrdf;
    std::printf("svbrdf: %s, %d pixels fitted (%d mixed), %d materials%s\n", solvers::core::TerminationName(svbrdf.summary.termination),
                svbrdf.summary.pixels_fitted, svbrdf.summary.pixels_mixed, svbrdf.summary.materials, svbrdf.gltf_path.empty() ? "" : ", glTF asset");
    ResultFields()["svbrdf"] = daemon::ToJson(svbrdf);
    ReportResultsDirectory(outcome.directory + "/results/svbrdf", ResultFields()["svbrdf"]);
    if (!svbrdf.usable()) return Fail(kExitFailed, "svbrdf gave no usable result: " + svbrdf.summary.message);
  }
  if (outcome.brdf) {
    const daemon::BrdfSolveResult& brdf = *outcome.brdf;
    std::printf("brdf:\n");
    if (brdf.measurement.IsSolutionUsable()) daemon::PrintMeasurement(stdout, brdf.measurement);
    if (brdf.selection) daemon::PrintSelection(stdout, *brdf.selection);
    if (!brdf.warning.empty()) std::printf("warning: %s\n", brdf.warning.c_str());
    ResultFields()["brdf"] = brdf.report;
    if (!brdf.results.empty()) ReportResultsDirectory(outcome.directory + "/results/brdf", ResultFields()["brdf"]);
    if (!brdf.usable())
      return Fail(brdf.refused_input() ? kExitUsage : kExitFailed, "brdf gave no usable result: " + brdf.failure());
  }
  return kExitOk;
}

CLI::App* Setup(CLI::App& app, Options* options) {
  CLI::App* sub = app.add_subcommand("run", "capture a recipe on its rig and run its solvers (no daemon needed)");
  sub->add_option("recipe", options->recipe, "recipe YAML")->required()->check(CLI::ExistingFile);
  sub->add_option("--rig", options->rig, "rig YAML (default: the rig the recipe names)")->check(CLI::ExistingFile);
  sub->add_option("--out", options->out, "run directory to create (default: runs/<recipe>-<UTC time>)");
  sub->add_flag("--no-solve", options->no_solve, "capture only");
  sub->add_flag("--nexus", options->nexus, "write the run and its solves as RUN/run.nxs when they end, as the recipe's export: {nexus: true} does (docs/nexus.md)");
  return sub;
}

const bool registered = RegisterCommand<Options, Setup, Execute>();

}  // namespace
}  // namespace photorig::app
