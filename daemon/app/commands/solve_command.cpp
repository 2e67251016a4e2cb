// photorig solve ps --run DIR [--method ...] [--shadow-sigma S] [--out DIR]

#include "../command.h"
#include "photorig/daemon/ps_pipeline.h"
#include "ps_report.h"

#include <filesystem>
#include <memory>

namespace photorig::app {
namespace {

struct Options {
  std::string run_dir, out;
  daemon::PhotometricStereoRequest request;
};

int Execute(const Options& options) {
  const std::string destination =
      options.out.empty() ? (std::filesystem::path(options.run_dir) / "results" / "ps").string() : options.out;
  const nlohmann::json report = daemon::SolvePhotometricStereoRun(options.run_dir, options.request, destination);
  PrintPhotometricStereoSummary(report);
  return report["termination"] == "success" ? 0 : 3;
}

CommandRunner Setup(CLI::App& app) {
  auto options = std::make_shared<Options>();
  CLI::App* solve = SubcommandGroup(app, "solve", "run a solver on stored data");
  CLI::App* ps = solve->add_subcommand("ps", "photometric stereo");
  ps->add_option("--run", options->run_dir, "run directory")->required()->check(CLI::ExistingDirectory);
  ps->add_option("--method", options->request.method, "lambertian | lambertian-l2")
      ->check(CLI::IsMember({"lambertian", "lambertian-l2"}));
  ps->add_option("--shadow-sigma", options->request.shadow_threshold_sigma, "shadow threshold in dark-noise sigmas")
      ->check(CLI::NonNegativeNumber);
  ps->add_option("--out", options->out, "output directory (default: RUN/results/ps)");
  return {ps, [options] { return Execute(*options); }};
}

const bool registered = RegisterCommand(Setup);

}  // namespace
}  // namespace photorig::app
