// photorig solve svbrdf (--run DIR [--accept-failed-capture] | --dataset DIR) [--mask PNG] [--out DIR] [--max-materials K] [--held-out N] [--no-gltf]
//                      [--refine-normals]

#include "../command.h"
#include "../command_output.h"
#include "../progress_display.h"
#include "photorig/daemon/pipelines/color_stack.h"
#include "photorig/daemon/pipelines/svbrdf_pipeline.h"
#include "ps_report.h"

#include <cstdio>

namespace photorig::app {
namespace {

namespace refl = solvers::reflectance;

struct Options {
  StackSource source;
  std::string mask, out;
  solvers::color::DemosaicMethod demosaic = solvers::color::DemosaicMethod::kBilinear;
  config::SvbrdfRequest request;
  bool no_gltf = false;
};

void PrintSummary(const daemon::SvbrdfResult& result) {
  std::fprintf(stderr, "svbrdf: %s, %d pixels fitted (%d mixed), %d materials\n",
               solvers::core::TerminationName(result.summary.termination), result.summary.pixels_fitted,
               result.summary.pixels_mixed, result.summary.materials);
  for (std::size_t m = 0; m < result.material_fits.size(); ++m) {
    const refl::MaterialFit& f = result.material_fits[m];
    std::fprintf(stderr, "  material %zu: %s, %d pixels, specular %.4g, shape %.4g\n", m,
                 solvers::brdf::ModelName(f.model), f.pixels, f.specular[0], f.shape);
  }
  for (refl::Warning w : result.summary.warnings) std::fprintf(stderr, "  warning: %s\n", refl::WarningName(w));
  if (result.normal_refinement)
    std::fprintf(stderr, "  normals refined: %s\n", result.normal_refinement->message.c_str());
  if (result.relighting && result.relighting->IsSolutionUsable())
    for (int m = 0; m < 3; ++m)
      std::fprintf(stderr, "  held-out RMSE %-15s %.5g (PSNR %.1f dB) over %zu lights\n",
                   refl::MethodName(static_cast<refl::Method>(m)), result.relighting->mean_rmse[m],
                   result.relighting->mean_psnr_db[m], result.relighting->held_out.size());
}

int Execute(const Options& options) {
  if (std::string why; !options.request.ps.IsValid(&why)) return Fail(kExitUsage, why);
  if (!options.source.given()) return Fail(kExitUsage, "give --run DIR or --dataset DIR");
  const std::string destination = options.source.ResultsDirectory(options.out, "svbrdf");
  daemon::ColorStackOptions color;
  color.demosaic = options.demosaic;
  daemon::PhotometricStereoInput input = options.source.Load(color);
  if (!options.mask.empty()) daemon::SetObjectMaskFromFile(options.mask, &input);
  ProgressDisplay progress;
  config::SvbrdfRequest request = options.request;
  request.progress = progress.Callback();
  request.export_gltf = !options.no_gltf;
  const daemon::SvbrdfResult result = daemon::SolveSvbrdfAndWrite(input, request, destination);
  progress.EndLine();
  PrintSummary(result);
  WarnOfFailedCapture(result.ps.capture);
  ResultFields() = daemon::ToJson(result);
  ReportResultsDirectory(destination);
  if (!result.usable()) return Fail(kExitFailed, "no usable result: " + result.summary.message);
  return kExitOk;
}

CLI::App* SetupSolveSvbrdf(CLI::App& app, Options* options) {
  CLI::App* svbrdf = SolveGroup(app)->add_subcommand(
      "svbrdf", "normals, per-pixel albedo and per-material lobes, held-out relighting and a glTF asset");
  AddStackSourceOptions(svbrdf, &options->source);
  svbrdf->add_option("--mask", options->mask, "PNG, nonzero = object")->check(CLI::ExistingFile);
  svbrdf->add_option("--out", options->out, "output directory (default: SOURCE/results/svbrdf)");
  AddChoice(svbrdf, "--method", &options->request.ps.method, solvers::ps::kMethodNames,
            "photometric stereo for the normals");
  svbrdf->add_option("--max-materials", options->request.max_materials, "largest number of materials tried (default 4)")
      ->check(CLI::Range(1, 16));
  svbrdf->add_option("--held-out", options->request.held_out_lights,
                     "lights held out one at a time for the relighting check, a stratified subset (default 8; 0 = all; -1 = skip)")
      ->check(CLI::Range(-1, 100000));
  AddChoice(svbrdf, "--demosaic", &options->demosaic, solvers::color::kDemosaicMethodNames, "Bayer runs");
  svbrdf->add_flag("--no-gltf", options->no_gltf, "do not write the glTF asset");
  svbrdf->add_flag("--refine-normals", options->request.refine_normals,
                   "refine the normals with the materials' lobes, alternating with the reflectance fit");
  return svbrdf;
}

const bool registered = RegisterCommand<Options, SetupSolveSvbrdf, Execute>();

}  // namespace
}  // namespace photorig::app
