// photorig solve brdf --run DIR [--accept-failed-capture] [--loss weighted|log] [--calibration reference|camera] [--out DIR]
//   (--json as every command: docs/cli.md)
//
// Gonioreflectometer frames -> BRDF samples (daemon/brdf_measurement.h: the
// bracket merged per pixel, calibrated against the rig's reference target,
// deviations from the sensor's noise model) -> every candidate model fitted
// and the one the data support chosen (solvers/brdf). A grey camera gives
// the same value in all three channels; a colour camera's are its own
// channels, each calibrated against the grey target.

#include "../command.h"
#include "../command_output.h"
#include "photorig/daemon/pipelines/internal/brdf_report.h"
#include "photorig/daemon/pipelines/brdf_solve.h"
#include "photorig/daemon/pipelines/internal/results_folder.h"
#include "photorig/daemon/capture/run_store.h"
#include "photorig/solvers/brdf/fit.h"
#include "ps_report.h"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>

namespace photorig::app {
namespace {

namespace brdf = photorig::solvers::brdf;
namespace fs = std::filesystem;

struct Options {
  std::string run_dir, out;
  brdf::FitLoss loss = brdf::FitLoss::kWeighted;
  bool calibrate_with_target = true;
  bool accept_failed_capture = false;
};

int Execute(const Options& options) {
  nlohmann::json doc = {{"run", options.run_dir}};
  // The report is also the command's --json document (main adds command, ok, exit_code).
  auto finish = [&](ExitCode code, const std::string& error) {
    ResultFields() = doc;
    return error.empty() ? static_cast<int>(code) : Fail(code, error);
  };
  config::BrdfRequest request;
  request.loss = options.loss;
  request.calibrate_with_target = options.calibrate_with_target;
  const std::string out = options.out.empty() ? (fs::path(options.run_dir) / "results" / "brdf").string() : options.out;
  daemon::BrdfSolveResult result;
  try {
    result = daemon::SolveBrdfAndWrite(options.run_dir, request, out, FailedCapturePolicy(options.accept_failed_capture));
  } catch (const daemon::ResultsWriteError& e) {
    return finish(kExitFailed, e.what());
  } catch (const daemon::FailedCaptureError& e) {
    return finish(kExitFailed, e.what());
  } catch (const std::exception& e) {  // an unreadable manifest or frame
    return finish(kExitUsage, e.what());
  }
  doc = result.report;
  const daemon::BrdfMeasurement& m = result.measurement;
  if (!m.IsSolutionUsable()) return finish(result.refused_input() ? kExitUsage : kExitFailed, m.message);
  FILE* text = stdout;  // under --json main points it at stderr
  daemon::PrintMeasurement(text, m);
  if (!result.selection) return finish(kExitFailed, result.failure());
  const brdf::SelectionSummary& s = *result.selection;
  doc["results"] = result.results;
  std::fprintf(text, "closest theta_h %.1f deg\n", s.min_theta_h_deg);
  daemon::PrintSelection(text, s);
  if (!result.warning.empty()) std::fprintf(text, "warning: %s\n", result.warning.c_str());
  WarnOfFailedCapture(result.capture);
  std::fprintf(text, "results: %s/\n", out.c_str());
  return finish(result.usable() ? kExitOk : kExitFailed, result.failure());
}

CLI::App* Setup(CLI::App& app, Options* options) {
  CLI::App* sub = SolveGroup(app)->add_subcommand("brdf", "fit BRDF models to a gonioreflectometer run and choose one");
  sub->add_option("--run", options->run_dir, "run directory")->required()->check(CLI::ExistingDirectory);
  AddAcceptFailedCaptureFlag(sub, &options->accept_failed_capture);
  AddChoice(sub, "--loss", &options->loss, brdf::kFitLossNames, "weighted: by each sample's deviation");
  AddChoice(sub, "--calibration", &options->calibrate_with_target, config::BrdfRequest::kCalibrationNames,
            "reference: the rig's reference target; camera: the camera's stated response")
      ->type_name("NAME");  // a bool behind the names: CLI11 would call it BOOLEAN
  sub->add_option("--out", options->out, "output directory (default: RUN/results/brdf)");
  return sub;
}

const bool registered = RegisterCommand<Options, Setup, Execute>();

}  // namespace
}  // namespace photorig::app
