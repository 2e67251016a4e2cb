// photorig: the command-line front end.
//   photorig run RECIPE [--rig FILE] [--out DIR] [--no-solve]
//   photorig solve ps --run DIR [--method lambertian|lambertian-l2] [--out DIR]
//   photorig validate RECIPE [--rig FILE]

#include "photorig/daemon/ps_pipeline.h"
#include "photorig/daemon/recipe.h"
#include "photorig/daemon/rig_config.h"
#include "photorig/daemon/run.h"
#include "photorig/daemon/yaml_node.h"
#include "signals.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <iostream>

namespace {

using namespace photorig::daemon;
using nlohmann::json;

void PrintPsSummary(const json& report) {
  std::printf("photometric stereo (%s): %s, %zu pixels solved, %.1f ms solve\n",
              report["method"].get<std::string>().c_str(), report["termination"].get<std::string>().c_str(),
              report["pixels"]["solved"].get<std::size_t>(), report["timings_ms"]["solve"].get<double>());
  if (!report["message"].get<std::string>().empty())
    std::printf("  solver says: %s\n", report["message"].get<std::string>().c_str());
  if (report.contains("ground_truth")) {
    const json& gt = report["ground_truth"];
    std::printf("  vs ground truth: mean %.3f deg, median %.3f deg, <5 deg %.1f%%, <10 deg %.1f%%, <15 deg %.1f%%, "
                "%zu of %zu pixels unresolved\n",
                gt["mean_angular_error_deg"].get<double>(), gt["median_angular_error_deg"].get<double>(),
                gt["percent_under_5deg"].get<double>(), gt["percent_under_10deg"].get<double>(),
                gt["percent_under_15deg"].get<double>(), gt["pixels_unresolved"].get<std::size_t>(),
                gt["pixels_with_truth"].get<std::size_t>());
  }
}

int Run(const std::string& recipe, const std::string& rig, const std::string& out, bool no_solve) {
  RunRequest request;
  request.recipe_path = recipe;
  request.rig_path = rig;
  request.output_directory = out;
  request.solve = !no_solve;
  request.show_progress = true;
  request.stop_requested = &photorig::app::g_stop_requested;
  const RunOutcome outcome = ExecuteRun(request);
  std::printf("run directory: %s\n", outcome.directory.c_str());
  std::printf("capture: %s, %d/%d frames, %.0f ms%s%s\n", outcome.capture.status.c_str(),
              outcome.capture.frames_written, outcome.capture.steps_total, outcome.capture.elapsed_ms,
              outcome.capture.reason.empty() ? "" : ": ", outcome.capture.reason.c_str());
  if (outcome.photometric_stereo) {
    PrintPsSummary(*outcome.photometric_stereo);
    std::printf("results: %s/results/ps/\n", outcome.directory.c_str());
    if ((*outcome.photometric_stereo)["termination"] != "success") return 3;
  }
  if (outcome.capture.status == "aborted") return 130;
  return outcome.capture.status == "complete" ? 0 : 2;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"photorig: capture and reconstruct with a light dome (simulated or real)"};
  app.require_subcommand(1);

  std::string recipe, rig, out, run_dir, method = "lambertian";
  bool no_solve = false;
  double shadow_sigma = 3.0;

  CLI::App* run = app.add_subcommand("run", "capture a recipe on its rig and run its solvers");
  run->add_option("recipe", recipe, "recipe YAML")->required()->check(CLI::ExistingFile);
  run->add_option("--rig", rig, "rig YAML (default: the rig the recipe names)")->check(CLI::ExistingFile);
  run->add_option("--out", out, "run directory to create (default: runs/<recipe>-<UTC time>)");
  run->add_flag("--no-solve", no_solve, "capture only");

  CLI::App* solve = app.add_subcommand("solve", "run a solver on a stored run");
  solve->require_subcommand(1);
  CLI::App* solve_ps = solve->add_subcommand("ps", "photometric stereo");
  solve_ps->add_option("--run", run_dir, "run directory")->required()->check(CLI::ExistingDirectory);
  solve_ps->add_option("--method", method, "lambertian | lambertian-l2")
      ->check(CLI::IsMember({"lambertian", "lambertian-l2"}));
  solve_ps->add_option("--shadow-sigma", shadow_sigma, "shadow threshold in dark-noise sigmas")
      ->check(CLI::NonNegativeNumber);
  solve_ps->add_option("--out", out, "output directory (default: RUN/results/ps)");

  CLI::App* validate = app.add_subcommand("validate", "check a recipe and its rig without touching devices");
  validate->add_option("recipe", recipe, "recipe YAML")->required()->check(CLI::ExistingFile);
  validate->add_option("--rig", rig, "rig YAML")->check(CLI::ExistingFile);

  CLI11_PARSE(app, argc, argv);
  spdlog::set_pattern("[%H:%M:%S.%e] [%^%l%$] %v");
  photorig::app::InstallStopHandlers();
  try {
    if (*run) return Run(recipe, rig, out, no_solve);
    if (*solve_ps) {
      PhotometricStereoRequest request;
      request.method = method;
      request.shadow_threshold_sigma = shadow_sigma;
      const std::string destination =
          out.empty() ? (std::filesystem::path(run_dir) / "results" / "ps").string() : out;
      const json report = SolvePhotometricStereoRun(run_dir, request, destination);
      PrintPsSummary(report);
      return report["termination"] == "success" ? 0 : 3;
    }
    if (*validate) {
      const Recipe parsed = LoadRecipe(recipe);
      const RigConfig rig_config = LoadRigConfig(ResolveRigPath(parsed, rig));
      const auto steps = CompileSteps(parsed, rig_config);
      std::printf("%s: valid; %zu steps on rig '%s' (%zu LEDs, camera %dx%d)\n", recipe.c_str(), steps.size(),
                  rig_config.name.c_str(), rig_config.lights.leds.size(), rig_config.camera.width,
                  rig_config.camera.height);
      return 0;
    }
  } catch (const ConfigError& e) {
    std::fprintf(stderr, "configuration error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
