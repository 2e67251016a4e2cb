#include "photorig/daemon/plan.h"

#include <sys/statvfs.h>

#include <filesystem>
#include <map>

namespace photorig::daemon {
namespace fs = std::filesystem;

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
  for (const CaptureStep& step : steps) {
    const double exposure_ms = step.exposure_us / 1000.0;
    total_ms += exposure_ms + options.step_overhead_ms;
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

nlohmann::json RunPlan::ToJson(const std::vector<CaptureStep>& steps) const {
  nlohmann::json list = nlohmann::json::array();
  for (const CaptureStep& step : steps) {
    nlohmann::json s = {{"index", step.index},
                        {"label", step.label},
                        {"kind", step.kind == CaptureStep::Kind::kDark ? "dark" : "light"},
                        {"exposure_us", step.exposure_us},
                        {"gain_db", step.gain_db},
                        {"levels", step.pattern.levels}};
    list.push_back(std::move(s));
  }
  return {{"ok", ok()},
          {"errors", errors},
          {"warnings", warnings},
          {"frames", estimate.frames},
          {"duration_s", estimate.duration_s},
          {"bytes", estimate.bytes},
          {"bytes_per_frame", estimate.bytes_per_frame},
          {"max_led_duty", max_led_duty},
          {"max_duty_led", max_duty_led},
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
