// photorig validate RECIPE [--rig FILE]: parse and compile without touching devices.

#include "../command.h"
#include "../command_output.h"
#include "photorig/config/recipe.h"
#include "photorig/config/solve_requests.h"

#include <cstdio>

namespace photorig::app {
namespace {

struct Options {
  std::string recipe, rig;
};

int Execute(const Options& options) {
  const config::RigConfig rig = config::LoadRigConfig(config::RecipeRigPath(options.recipe, options.rig));
  const config::Recipe recipe = config::LoadRecipe(options.recipe, rig);
  const auto steps = config::CompileSteps(recipe, rig);
  std::printf("%s: valid; %zu steps on rig '%s' (%zu LEDs, camera %dx%d)\n", options.recipe.c_str(), steps.size(),
              rig.name.c_str(), rig.lights.leds.size(), rig.camera.width, rig.camera.height);
  ResultFields() = {{"recipe", options.recipe}, {"rig", rig.path}, {"rig_name", rig.name}, {"steps", steps.size()},
                    {"leds", rig.lights.leds.size()}, {"camera", {{"width", rig.camera.width}, {"height", rig.camera.height}}}};
  return kExitOk;
}

CLI::App* Setup(CLI::App& app, Options* options) {
  CLI::App* sub = app.add_subcommand("validate", "check a recipe and its rig without touching devices");
  sub->add_option("recipe", options->recipe, "recipe YAML")->required()->check(CLI::ExistingFile);
  sub->add_option("--rig", options->rig, "rig YAML")->check(CLI::ExistingFile);
  return sub;
}

const bool registered = RegisterCommand<Options, Setup, Execute>();

}  // namespace
}  // namespace photorig::app
