// photorig solve ps (--run DIR [--accept-failed-capture] [--rig RIG] | --dataset DIR) [--method ...] [--mask PNG] [--out DIR]
//                  [--demosaic bilinear|edge-aware] [--color-model FILE] ...
// photorig export diligent --run DIR --out DIR

#include "../command.h"
#include "../command_output.h"
#include "../progress_display.h"
#include "../signals.h"
#include "photorig/daemon/pipelines/diligent.h"
#include "photorig/daemon/pipelines/ps_pipeline.h"
#include "ps_report.h"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <thread>

namespace photorig::app {
namespace {

struct Options {
  StackSource source;
  std::string mask, out, rig;
  std::string commit_gate;  // tests: hold the finished solve while this file exists
  solvers::color::DemosaicMethod demosaic = solvers::color::DemosaicMethod::kBilinear;
  std::string color_model;
  config::PhotometricStereoRequest request;
};

struct StoppedBeforeCommit : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Runs between writing the results and renaming them into place. A stop
// request (SIGTERM from Slurm's scancel or pre-emption, Ctrl-C) ends the
// solve there, leaving the previous results as they were.
void BeforeCommit(const std::string& commit_gate) {
  while (!commit_gate.empty() && std::filesystem::exists(commit_gate) && !g_stop_requested.load())
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  if (g_stop_requested.load()) throw StoppedBeforeCommit("stopped before the results were put in place");
}

int Execute(const Options& options) {
  if (std::string why; !options.request.IsValid(&why)) return Fail(kExitUsage, why);
  if (!options.source.given()) return Fail(kExitUsage, "give --run DIR or --dataset DIR");
  const std::string destination = options.source.ResultsDirectory(options.out, "ps");
  daemon::ColorStackOptions color;
  color.demosaic = options.demosaic;
  color.color_model_path = options.color_model;
  if (!options.source.from_run() && !options.color_model.empty())
    return Fail(kExitUsage, "--color-model applies to runs (a DiLiGenT folder's images are already RGB)");
  daemon::PhotometricStereoInput input = options.source.Load(color);
  if (!options.rig.empty()) daemon::ApplyRigCalibration(options.rig, &input);
  if (!options.mask.empty()) daemon::SetObjectMaskFromFile(options.mask, &input);
  ProgressDisplay progress;
  config::PhotometricStereoRequest request = options.request;
  request.progress = progress.Callback();
  daemon::PhotometricStereoResult result;
  try {
    result = daemon::SolveAndWrite(input, request, destination, [&options] { BeforeCommit(options.commit_gate); });
  } catch (const StoppedBeforeCommit& e) {
    progress.EndLine();
    return Fail(kExitInterrupted, std::string(e.what()) + "; " + destination + " is unchanged");
  }
  progress.EndLine();
  PrintPhotometricStereoSummary(result);
  WarnOfFailedCapture(result.capture);
  ResultFields() = daemon::ToJson(result);
  ReportResultsDirectory(destination);
  if (!result.usable()) return Fail(kExitFailed, "no usable result: " + result.summary.message);
  return kExitOk;
}

CLI::App* SetupSolve(CLI::App& app, Options* options) {
  CLI::App* ps = SolveGroup(app)->add_subcommand("ps", "photometric stereo on a run or a DiLiGenT-layout folder");
  AddStackSourceOptions(ps, &options->source);
  AddChoice(ps, "--method", &options->request.method, solvers::ps::kMethodNames, "photometric stereo method");
  AddChoice(ps, "--derivative", &options->request.derivative, solvers::ps::kBlinnPhongDerivativeNames,
            "Blinn-Phong fit: the lanes' closed form, or per pixel with an autodiff method");
  AddIntegratorOption(ps, &options->request);
  ps->add_flag("--assume-distant", options->request.assume_distant,
               "solve a rig with LED positions as if its LEDs were distant (refused beyond --max-distant-bias)");
  ps->add_flag_callback("--no-fill", [options] { options->request.fill_unresolved = false; },
                        "leave masked pixels without a normal where their own samples give none (default: "
                        "interpolated from their neighbours, flagged filled)");
  ps->add_option("--max-distant-bias", options->request.max_distant_bias_deg,
                 "largest predicted bias of the distant model, in degrees, that is solved (default 0.5)")
      ->check(CLI::Range(1e-3, 90.0));
  ps->add_option("--shadow-sigma", options->request.shadow_threshold_sigma, "shadow threshold in read-noise sigmas (from dark frames, else estimated)")
      ->check(CLI::NonNegativeNumber);
  ps->add_option("--max-condition", options->request.max_condition_number,
                 "largest condition number of a pixel's lit light directions (default 1000)")
      ->check(CLI::PositiveNumber);
  ps->add_option("--mask", options->mask,
                 "PNG, nonzero = object: solve only there (default: the dataset's mask.png, else from the dark and lit frames)")
      ->check(CLI::ExistingFile);
  auto* rig = ps->add_option("--rig", options->rig,
                             "rig YAML whose LEDs and camera replace those the run recorded (a calibration made after "
                             "the capture)")
                  ->check(CLI::ExistingFile);
  rig->excludes("--dataset");
  ps->add_option("--out", options->out, "output directory, replaced whole as the solve ends (default: SOURCE/results/ps)");
  // For tests of pre-emption (tests/slurm): a task held with its results written but not yet in place.
  ps->add_option("--commit-gate", options->commit_gate, "wait while FILE exists before putting the results in place")
      ->group("");
  AddChoice(ps, "--demosaic", &options->demosaic, solvers::color::kDemosaicMethodNames,
            "Bayer runs (bilinear is linear, so exact with dark subtraction)");
  ps->add_option("--color-model", options->color_model,
                 "colour model (photorig calibrate color) for a colour run (default: the one its rig named)")
      ->check(CLI::ExistingFile);
  return ps;
}

struct ExportOptions {
  std::string run_dir, out;
};

CommandRunner SetupExport(CLI::App& app) {
  auto options = std::make_shared<ExportOptions>();
  CLI::App* group = SubcommandGroup(app, "export", "write stored data in other tools' formats");
  CLI::App* diligent = group->add_subcommand("diligent", "a run as a DiLiGenT-layout folder");
  diligent->add_option("--run", options->run_dir, "run directory")->required()->check(CLI::ExistingDirectory);
  diligent->add_option("--out", options->out, "folder to write")->required();
  return {diligent, [options] {
            daemon::ExportDiligent(options->run_dir, options->out);
            std::printf("wrote %s/\n", options->out.c_str());
            ResultFields()["run_directory"] = options->run_dir;
            ResultFields()["out"] = options->out;
            return kExitOk;
          }};
}

const bool registered_solve = RegisterCommand<Options, SetupSolve, Execute>();
const bool registered_export = RegisterCommand(SetupExport);

}  // namespace
}  // namespace photorig::app
