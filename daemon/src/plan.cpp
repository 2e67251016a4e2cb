#include "photorig/daemon/plan.h"

#include "photorig/sim/gonio.h"

#include <sys/statvfs.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>

namespace photorig::daemon {
namespace fs = std::filesystem;

namespace {

// The goniometer moves one axis at a time, each ending with the settle time.
double MoveMs(const MotionConfig& motion, const std::map<std::string, double>& from,
              const std::map<std::string, double>& to) {
  double ms = 0.0;
  for (const auto& [id, target] : to) {
    const double distance = std::abs(target - from.at(id));
    if (distance > motion.settle.tolerance_deg)
      ms += 1000.0 * sim::TrapezoidMove(distance, motion.profile).duration_s() + motion.settle.settle_ms;
  }
  return ms;
}

}  // namespace

std::map<std::string, double> PoseTargets(const GonioPose& pose) {
  return {{"light_arm", pose.light_arm_deg},
          {"camera_arm", pose.camera_arm_deg},
          {"sample_rotation", pose.sample_rotation_deg}};
}

bool PlanOptions::IsValid(std::string* why) const {
  if (!(step_overhead_ms >= 0)) {
    if (why) *why = "step_overhead_ms must be >= 0";
    return false;
  }
  if (!(max_led_duty > 0 && max_led_duty <= 1)) {
    if (why) *why = "max_led_duty must be within (0, 1]";
    return false;
  }
  return true;
}

RunPlan PlanRun(const Recipe& recipe, const RigConfig& rig, const std::vector<CaptureStep>& steps,
                const PlanOptions& options) {
  RunPlan plan;
  std::string why;
  if (!options.IsValid(&why)) plan.errors.push_back("plan options: " + why);
  const std::uint64_t pixels = static_cast<std::uint64_t>(rig.camera.width) * rig.camera.height;
  plan.estimate.frames = static_cast<int>(steps.size());
  plan.estimate.bytes_per_frame = pixels * 2 + 4096;
  plan.estimate.bytes = plan.estimate.bytes_per_frame * steps.size() + 512 * steps.size() + 65536;
  if (rig.IsSimulated()) plan.estimate.bytes += pixels * (12 + 4 + 1);  // ground truth maps

  std::map<int, double> lit_ms;  // by channel
  double total_ms = 0.0;
  std::map<std::string, double> axes_at;  // every axis starts from its home
  if (rig.motion)
    for (const AxisConfig& axis : rig.motion->axes) axes_at[axis.id] = axis.limits.home_deg;
  for (const CaptureStep& step : steps) {
    const double exposure_ms = step.exposure_us / 1000.0;
    total_ms += exposure_ms + options.step_overhead_ms;
    if (step.pose) {
      if (!rig.motion) {
        plan.errors.push_back("step " + step.label + ": a pose on rig '" + rig.name + "', which has no motion");
        continue;
      }
      const std::map<std::string, double> target = PoseTargets(*step.pose);
      if (std::string why = rig.motion->CheckPose(target); !why.empty())
        plan.errors.push_back("step " + step.label + ": " + why);
      // Two arms on one circle cannot pass each other: the side each is on stays as the first pose set it.
      for (const drivers::SeparationConstraint& c : rig.motion->constraints) {
        const double before = axes_at[c.axis_a] - axes_at[c.axis_b], after = target.at(c.axis_a) - target.at(c.axis_b);
        if (before * after < 0.0)
          plan.errors.push_back("step " + step.label + ": " + c.axis_a + " and " + c.axis_b +
                                " would have to pass each other (they cannot cross)");
      }
      const double move_ms = MoveMs(*rig.motion, axes_at, target);
      plan.move_s += move_ms / 1000.0;
      total_ms += move_ms;
      for (const auto& [id, deg] : target) axes_at[id] = deg;
    }
    for (std::size_t channel = 0; channel < step.pattern.levels.size(); ++channel) {
      const double level = step.pattern.levels[channel];
      if (level < 0.0 || level > 1.0)
        plan.errors.push_back("step " + step.label + ": channel " + std::to_string(channel) + " level " +
                              std::to_string(level) + " outside [0, 1]");
      if (level > 0.0) lit_ms[static_cast<int>(channel)] += exposure_ms;
    }
  }
  plan.estimate.duration_s = total_ms / 1000.0;
  for (const auto& [channel, ms] : lit_ms) {
    const double duty = total_ms > 0 ? ms / total_ms : 0.0;
    if (duty > plan.max_led_duty) {
      plan.max_led_duty = duty;
      plan.max_duty_led = rig.lights.leds.at(channel).id;
    }
  }
  if (plan.max_led_duty > options.max_led_duty)
    plan.errors.push_back("LED " + std::to_string(plan.max_duty_led) + " would be lit " +
                          std::to_string(plan.max_led_duty * 100) + "% of the run, above the " +
                          std::to_string(options.max_led_duty * 100) + "% limit");
  if (steps.empty()) plan.warnings.push_back("recipe " + recipe.path + " compiles to no steps");
  return plan;
}

nlohmann::json RunPlan::ToJson(const std::vector<CaptureStep>& steps, std::size_t max_listed_steps) const {
  nlohmann::json list = nlohmann::json::array();
  const std::size_t listed = std::min(steps.size(), max_listed_steps);
  for (std::size_t i = 0; i < listed; ++i) {
    const CaptureStep& step = steps[i];
    nlohmann::json s = {{"index", step.index},
                        {"label", step.label},
                        {"kind", CaptureStepKindName(step.kind)},
                        {"group", step.group},
                        {"repeat", step.repeat},
                        {"exposure_us", step.exposure_us},
                        {"gain_db", step.gain_db},
                        {"levels", step.pattern.levels}};
    if (step.pose)
      s["pose"] = {{"light_arm_deg", step.pose->light_arm_deg},
                   {"camera_arm_deg", step.pose->camera_arm_deg},
                   {"sample_rotation_deg", step.pose->sample_rotation_deg}};
    list.push_back(std::move(s));
  }
  return {{"ok", ok()},
          {"errors", errors},
          {"warnings", warnings},
          {"frames", estimate.frames},
          {"duration_s", estimate.duration_s},
          {"move_s", move_s},
          {"bytes", estimate.bytes},
          {"bytes_per_frame", estimate.bytes_per_frame},
          {"max_led_duty", max_led_duty},
          {"max_duty_led", max_duty_led},
          {"steps_listed", listed},
          {"steps", list}};
}

std::uint64_t FreeBytes(const std::string& path) {
  fs::path probe = fs::absolute(path);
  while (!probe.empty() && !fs::exists(probe) && probe != probe.parent_path()) probe = probe.parent_path();
  struct statvfs info {};
  if (::statvfs(probe.c_str(), &info) != 0) return 0;
  return static_cast<std::uint64_t>(info.f_bavail) * info.f_frsize;
}

}  // namespace photorig::daemon
