// photorig calibrate radiance --run DIR --albedo A [--exponent keep|fit|choose] [--plane-height-mm H]
//   [--rig IN.yaml] [--out-rig NEW.yaml] [--out DIR (default RUN/results/led-radiance)]
// Each near LED's intensity and radiance profile from a run that photographed
// a matte plane of known albedo under every LED, written as a report and a
// new rig YAML (an existing file is never overwritten).

#include "../command.h"
#include "../command_output.h"
#include "photorig/daemon/pipelines/led_radiance.h"

#include <cstdio>
#include <filesystem>

namespace photorig::app {
namespace {

struct Options {
  daemon::LedRadianceRequest request;
};

int Execute(const Options& o) {
  const daemon::LedRadianceRequest& request = o.request;
  if (std::string why; !request.options.IsValid(&why)) return Fail(kExitUsage, "calibrate radiance: " + why);
  const daemon::LedRadianceResult result = daemon::CalibrateLedRadianceRun(request);
  const solvers::lighting::LedRadianceSummary& s = result.summary;
  std::printf("plane: %d pixels; %d of %zu LEDs usable\n", s.plane_pixels, s.usable, s.leds.size());
  for (std::size_t k = 0; k < s.leds.size(); ++k) {
    const solvers::lighting::LedRadianceEstimate& e = s.leds[k];
    std::printf("LED %3d: intensity %.4f +- %.4f (stated %.4f), cos exponent %.3f%s, model error %.2f %%%s%s\n",
                result.led_ids[k], e.intensity, e.intensity_std, result.stated_intensity[k], e.cos_exponent,
                e.exponent_fitted ? " (fitted)" : " (kept)", 100.0 * e.model_error, e.usable ? "" : ": ",
                e.usable ? "" : e.note.c_str());
  }
  ResultFields() = daemon::ToJson(request, result);
  ResultFields()["out"] = result.output_directory;
  ResultFields()["out_rig"] = result.rig_written ? request.out_rig : "";
  if (!s.IsSolutionUsable()) {
    const bool usage = s.termination == solvers::core::Termination::kInvalidOptions ||
                       s.termination == solvers::core::Termination::kInvalidInput;
    return Fail(usage ? kExitUsage : kExitFailed, "calibrate radiance: " + s.message);
  }
  std::printf("results: %s\n", result.output_directory.c_str());
  if (result.rig_written) std::printf("rig written: %s\n", request.out_rig.c_str());
  return kExitOk;
}

CLI::App* Setup(CLI::App& app, Options* o) {
  daemon::LedRadianceRequest& request = o->request;
  CLI::App* radiance = CalibrateGroup(app)->add_subcommand(
      "radiance", "near LEDs' intensities and radiance profiles from a matte plane");
  radiance->add_option("--run", request.run_directory, "run with a dark frame and one frame of the plane per LED")
      ->required()
      ->check(CLI::ExistingDirectory);
  radiance->add_option("--albedo", request.options.albedo, "the plane's diffuse albedo, (0, 1]")->required();
  AddChoice(radiance, "--exponent", &request.options.exponent, solvers::lighting::kExponentRuleNames,
            "the LEDs' cos exponents");
  radiance->add_option("--plane-height-mm", request.options.plane_height_mm,
                       "height of the plane's surface above the sample plane (mm)")
      ->capture_default_str();
  radiance->add_option("--rig", request.base_rig,
                       "rig YAML to start from: its LED positions and camera are fitted with, and it is copied "
                       "(default: the run's)")
      ->check(CLI::ExistingFile);
  radiance->add_option("--out-rig", request.out_rig, "new rig YAML with the calibrated LEDs; must not exist");
  radiance->add_option("--out", request.output_directory, "output directory (default RUN/results/led-radiance)");
  return radiance;
}

const bool registered = RegisterCommand<Options, Setup, Execute>();

}  // namespace
}  // namespace photorig::app
