// photorigd: the rig daemon. For now it executes the recipes it is given, one
// after another, with the same core as `photorig run`, and exits; on SIGTERM
// or SIGINT it stops after the current step with the lights off.
//   photorigd --data-root DIR RECIPE...

#include "photorig/daemon/run.h"
#include "photorig/daemon/yaml_node.h"
#include "signals.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <filesystem>

int main(int argc, char** argv) {
  CLI::App app{"photorigd: runs capture recipes on the rig"};
  std::string data_root = "runs";
  std::vector<std::string> recipes;
  app.add_option("--data-root", data_root, "where run directories are created");
  app.add_option("recipes", recipes, "recipes to run in order")->check(CLI::ExistingFile)->required();
  CLI11_PARSE(app, argc, argv);
  photorig::app::InstallStopHandlers();
  spdlog::info("photorigd: {} recipe(s), data root {}", recipes.size(), data_root);

  int failures = 0;
  for (const std::string& recipe : recipes) {
    if (photorig::app::g_stop_requested) break;
    photorig::daemon::RunRequest request;
    request.recipe_path = recipe;
    request.show_progress = false;
    request.stop_requested = &photorig::app::g_stop_requested;
    try {
      const std::string stem = std::filesystem::path(recipe).stem().string();
      int attempt = 0;
      do {
        request.output_directory = (std::filesystem::path(data_root) / (stem + "-" + std::to_string(attempt++))).string();
      } while (std::filesystem::exists(request.output_directory));
      const auto outcome = photorig::daemon::ExecuteRun(request);
      spdlog::info("{}: {} ({})", recipe, outcome.capture.status, outcome.directory);
      failures += outcome.capture.status != "complete";
    } catch (const std::exception& e) {
      spdlog::error("{}: {}", recipe, e.what());
      ++failures;
    }
  }
  return failures == 0 ? 0 : 1;
}
