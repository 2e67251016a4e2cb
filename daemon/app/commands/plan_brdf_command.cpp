// photorig plan brdf --rig RIG [--theta-h MIN MAX STEPS] [--theta-d MIN MAX STEPS]
//                    [--phi-d MIN MAX STEPS] [--rotation DEG]
//
// A gonioreflectometer pose plan uniform in Rusinkiewicz's angles
// (solvers/brdf/pose_plan.h) for the rig's arms, printed as a recipe `poses:`
// step to paste into a recipe's capture steps (a recipe's `poses: {plan: ...}`
// step makes the same plan itself when it loads). Refused configurations and
// why go to stderr. Every planned pose is checked again by the rig's own limits and
// separation constraints, as dry-run will.

#include "../command.h"
#include "../command_output.h"
#include "photorig/config/recipe.h"
#include "photorig/config/solve_requests.h"
#include "photorig/config/rig.h"
#include "photorig/config/sim.h"
#include "photorig/config/yaml_node.h"
#include "photorig/solvers/brdf/pose_plan.h"

#include <cmath>
#include <cstdio>
#include <map>
#include <optional>

namespace photorig::app {
namespace {

namespace brdf = photorig::solvers::brdf;

struct Options {
  std::string rig;
  std::vector<double> theta_h = {0.0, 60.0, 13.0}, theta_d = {10.0, 70.0, 13.0}, phi_d = {0.0, 0.0, 1.0};
  double rotation_deg = 0.0;
};

int Execute(const Options& o) {
  const config::RigConfig rig = config::LoadRigConfig(o.rig);
  const std::optional<brdf::GonioArms> arms = rig.motion ? config::GonioArmsOf(*rig.motion) : std::nullopt;
  if (!arms) return Fail(kExitUsage, o.rig + " has no light_arm and camera_arm axes (not a gonioreflectometer)");

  brdf::SamplingSpec spec;
  spec.theta_h_min_deg = o.theta_h[0];
  spec.theta_h_max_deg = o.theta_h[1];
  spec.theta_h_steps = static_cast<int>(o.theta_h[2]);
  spec.theta_d_min_deg = o.theta_d[0];
  spec.theta_d_max_deg = o.theta_d[1];
  spec.theta_d_steps = static_cast<int>(o.theta_d[2]);
  spec.phi_d_min_deg = o.phi_d[0];
  spec.phi_d_max_deg = o.phi_d[1];
  spec.phi_d_steps = static_cast<int>(o.phi_d[2]);
  if (std::string why; !spec.IsValid(&why)) return Fail(kExitUsage, why);
  brdf::PosePlanOptions plan_options;
  plan_options.sample_rotation_deg = o.rotation_deg;
  const brdf::PosePlan plan = brdf::PlanPoses(brdf::UniformHalfDiffGrid(spec), *arms, plan_options);
  if (plan.termination == solvers::core::Termination::kInvalidOptions) return Fail(kExitUsage, o.rig + ": " + plan.message);
  constexpr double kDeg = 180.0 / M_PI;
  for (const brdf::RefusedPose& r : plan.refused)
    std::fprintf(stderr, "refused theta_h %.2f theta_d %.2f phi_d %.2f: %s\n", r.requested.theta_h * kDeg,
                 r.requested.theta_d * kDeg, r.requested.phi_d * kDeg, r.reason.c_str());
  std::printf("# %zu poses uniform in theta_h [%g, %g] x%d, theta_d [%g, %g] x%d, phi_d [%g, %g] x%d on %s;\n"
              "# %zu refused, %d grazing; arm travel %.0f deg (%.0f deg in grid order)\n"
              "# in a recipe, the same plan: - poses: {plan: {theta_h_deg: {min: %g, max: %g, steps: %d}, "
              "theta_d_deg: {min: %g, max: %g, steps: %d}, phi_d_deg: {min: %g, max: %g, steps: %d}, "
              "sample_rotation_deg: %g}}\n",
              plan.poses.size(), spec.theta_h_min_deg, spec.theta_h_max_deg, spec.theta_h_steps,
              spec.theta_d_min_deg, spec.theta_d_max_deg, spec.theta_d_steps, spec.phi_d_min_deg, spec.phi_d_max_deg,
              spec.phi_d_steps, o.rig.c_str(), plan.refused.size(), plan.grazing, plan.planned_move_deg,
              plan.requested_order_move_deg, spec.theta_h_min_deg, spec.theta_h_max_deg, spec.theta_h_steps,
              spec.theta_d_min_deg, spec.theta_d_max_deg, spec.theta_d_steps, spec.phi_d_min_deg, spec.phi_d_max_deg,
              spec.phi_d_steps, o.rotation_deg);
  std::printf("- poses:\n    list:\n");
  for (const brdf::PlannedPose& p : plan.poses) {
    const std::map<std::string, double> target = {{"light_arm", p.arms.light_arm_deg},
                                                  {"camera_arm", p.arms.camera_arm_deg},
                                                  {"sample_rotation", p.arms.sample_rotation_deg}};
    if (std::string why = rig.motion->CheckPose(target); !why.empty())
      return Fail(kExitFailed, "planned pose refused by the rig: " + why);
    std::printf("      - {light_arm_deg: %.3f, camera_arm_deg: %.3f, sample_rotation_deg: %.3f}\n",
                p.arms.light_arm_deg, p.arms.camera_arm_deg, p.arms.sample_rotation_deg);
  }
  ResultFields() = {{"rig", o.rig},
                    {"poses", plan.poses.size()},
                    {"refused", plan.refused.size()},
                    {"grazing", plan.grazing},
                    {"arm_travel_deg", plan.planned_move_deg},
                    {"grid_order_travel_deg", plan.requested_order_move_deg}};
  return plan.IsSolutionUsable() ? kExitOk : Fail(kExitFailed, plan.message);
}

CLI::App* Setup(CLI::App& app, Options* options) {
  CLI::App* group = SubcommandGroup(app, "plan", "plan captures without touching any device");
  CLI::App* sub = group->add_subcommand("brdf", "gonioreflectometer poses uniform in (theta_h, theta_d, phi_d), as a recipe step");
  sub->add_option("--rig", options->rig, "gonioreflectometer rig YAML")->required()->check(CLI::ExistingFile);
  sub->add_option("--theta-h", options->theta_h, "MIN MAX STEPS in degrees (default 0 60 13)")->expected(3);
  sub->add_option("--theta-d", options->theta_d, "MIN MAX STEPS in degrees (default 10 70 13)")->expected(3);
  sub->add_option("--phi-d", options->phi_d, "MIN MAX STEPS in degrees (default 0 0 1: in-plane)")->expected(3);
  sub->add_option("--rotation", options->rotation_deg, "where the turntable stays, degrees (default 0)");
  return sub;
}

const bool registered = RegisterCommand<Options, Setup, Execute>();

}  // namespace
}  // namespace photorig::app
