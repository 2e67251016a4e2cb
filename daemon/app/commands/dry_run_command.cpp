// photorig dry-run RECIPE [--rig FILE] [--out DIR]: compiles the
// recipe to its step list, checks limits and free space, and estimates
// duration and data size, without touching any device.

#include "../command.h"
#include "../command_output.h"
#include "photorig/daemon/capture/plan.h"
#include "photorig/config/recipe.h"
#include "photorig/config/solve_requests.h"

#include <cstdio>

namespace photorig::app {
namespace {

struct Options {
  std::string recipe, rig, out = "runs";
  double max_led_duty = 1.0;
  bool list_steps = false;
};

int Execute(const Options& options) {
  const config::RigConfig rig = config::LoadRigConfig(config::RecipeRigPath(options.recipe, options.rig));
  const config::Recipe recipe = config::LoadRecipe(options.recipe, rig);
  const auto steps = config::CompileSteps(recipe, rig);
  daemon::PlanOptions plan_options;
  plan_options.max_led_duty = options.max_led_duty;
  daemon::RunPlan plan = daemon::PlanRun(recipe, rig, steps, plan_options);
  const std::uint64_t free_bytes = daemon::FreeBytes(options.out);
  if (free_bytes < plan.estimate.bytes)
    plan.errors.push_back("not enough free space under " + options.out + ": about " +
                          std::to_string(plan.estimate.bytes >> 20) + " MiB needed, " + std::to_string(free_bytes >> 20) +
                          " MiB free");
  ResultFields() = plan.ToJson(steps);
  ResultFields()["free_bytes"] = free_bytes;
  if (options.list_steps)
    for (const auto& step : steps) {
      int lit = 0;
      for (double level : step.pattern->levels) lit += level > 0.0;
      std::printf("  %-32s %-7s exposure %8.0f us  gain %4.1f dB  %2d LED%s lit", step.label.c_str(),
                  config::CaptureStepKindName(step.kind), step.exposure_us, step.gain_db, lit, lit == 1 ? "" : "s");
      if (step.pose)
        std::printf("  light %+.1f camera %+.1f rotation %+.1f deg", step.pose->light_arm_deg, step.pose->camera_arm_deg,
                    step.pose->sample_rotation_deg);
      std::printf("\n");
    }
  std::printf("%s on rig '%s': %d frames, about %.1f s, %.1f MiB (%.1f MiB free)\n", options.recipe.c_str(),
              rig.name.c_str(), plan.estimate.frames, plan.estimate.duration_s, plan.estimate.bytes / 1048576.0,
              free_bytes / 1048576.0);
  if (plan.move_s > 0) std::printf("arm moves: about %.1f s of that\n", plan.move_s);
  if (const auto& a = plan.adaptive)
    std::printf("adaptive plan: a coarse pass of %d poses, then up to %d x %d poses added after the coarse pass "
                "(at most %d frames, %.1f s more: at most %.1f s in all)\n",
                a->coarse_poses, a->passes, a->added_poses, a->max_frames, a->max_duration_s,
                plan.estimate.duration_s + a->max_duration_s);
  if (plan.max_duty_led >= 0)
    std::printf("busiest LED: %d, lit %.1f%% of the run\n", plan.max_duty_led, 100.0 * plan.max_led_duty);
  for (const auto& warning : plan.warnings) std::printf("warning: %s\n", warning.c_str());
  if (plan.ok()) return kExitOk;
  std::string why;
  for (const auto& error : plan.errors) why += (why.empty() ? "" : "; ") + error;
  return Fail(kExitUsage, why);
}

CLI::App* Setup(CLI::App& app, Options* options) {
  CLI::App* sub = app.add_subcommand("dry-run", "compile a recipe, check limits and estimate time and size (no devices)");
  sub->add_option("recipe", options->recipe, "recipe YAML")->required()->check(CLI::ExistingFile);
  sub->add_option("--rig", options->rig, "rig YAML (default: the rig the recipe names)")->check(CLI::ExistingFile);
  sub->add_option("--out", options->out, "where the run would be stored (for the free-space check)")->capture_default_str();
  sub->add_option("--max-led-duty", options->max_led_duty, "highest fraction of the run an LED may be lit")
      ->capture_default_str();
  sub->add_flag("--steps", options->list_steps, "list every step");
  return sub;
}

const bool registered = RegisterCommand<Options, Setup, Execute>();

}  // namespace
}  // namespace photorig::app
