#include "photorig/daemon/capture/plan.h"

#include "photorig/sim/gonio.h"

#include <malloc.h>
#include <sys/statvfs.h>

#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <map>
#include <mutex>

namespace photorig::daemon {
using solvers::core::Refuse;
namespace fs = std::filesystem;

namespace {

// The goniometer moves one axis at a time, each ending with the settle time.
double MoveMs(const config::MotionConfig& motion, const std::map<std::string, double>& from,
              const std::map<std::string, double>& to) {
  double ms = 0.0;
  for (const auto& [id, target] : to) {
    const double distance = std::abs(target - from.at(id));
    if (distance > motion.settle.tolerance_deg)
      ms += 1000.0 * sim::TrapezoidMove(distance, motion.profile).duration_s() + motion.settle.settle_ms;
  }
  return ms;
}

// One LED's exposures against its safety limits, fed in capture order: the
// longest exposure, and the most lit time in any window of window_ms. The
// windows that hold the most start at an exposure's start; only the
// exposures inside the current window are kept, so a plan of 100 000 flats
// costs no more than a short one.
class DutyWindow {
 public:
  explicit DutyWindow(double window_ms) : window_ms_(window_ms) {}
  void Add(double start_ms, double length_ms) {
    longest_ms_ = std::max(longest_ms_, length_ms);
    while (!open_.empty() && start_ms >= open_.front().first + window_ms_) CloseFirst();
    open_.emplace_back(start_ms, length_ms);
    in_window_ms_ += length_ms;
  }
  double longest_ms() const { return longest_ms_; }
  double WorstMs() {
    while (!open_.empty()) CloseFirst();
    return worst_ms_;
  }

 private:
  // The window starting at the first open exposure holds every open one; the
  // last may reach past the window's end: only its part inside counts.
  void CloseFirst() {
    const double window_end = open_.front().first + window_ms_;
    const auto& last = open_.back();
    worst_ms_ = std::max(worst_ms_, in_window_ms_ - std::max(0.0, last.first + last.second - window_end));
    in_window_ms_ -= open_.front().second;
    open_.pop_front();
  }

  double window_ms_;
  std::deque<std::pair<double, double>> open_;  // (start, length) in ms
  double in_window_ms_ = 0.0, worst_ms_ = 0.0, longest_ms_ = 0.0;
};

// The rig's LED limits (lights.options.safety, the same the driver layer
// enforces) against the planned exposures: a plan that the safety layer would
// cut mid-run is refused before it starts.
void CheckLightSafety(const config::RigConfig& rig, std::map<int, DutyWindow>& lit, RunPlan* plan) {
  const drivers::LightSafetyOptions& safety = rig.lights.safety;
  for (auto& [channel, window] : lit) {
    if (channel >= static_cast<int>(rig.lights.leds.size())) continue;
    const drivers::ChannelLimits& limits = safety.For(channel);
    const int led = rig.lights.leds[static_cast<std::size_t>(channel)].id;
    if (limits.max_on_ms > 0 && window.longest_ms() > limits.max_on_ms)
      plan->errors.push_back("LED " + std::to_string(led) + " would stay lit " + std::to_string(window.longest_ms()) +
                             " ms in one exposure, above the rig's max_on_ms of " + std::to_string(limits.max_on_ms) +
                             " ms (lights.options.safety)");
    if (limits.max_duty >= 1.0) continue;
    const double duty = window.WorstMs() / safety.duty_window_ms;
    if (duty > limits.max_duty)
      plan->errors.push_back("LED " + std::to_string(led) + " would be lit " + std::to_string(duty * 100) + "% of a " +
                             std::to_string(safety.duty_window_ms / 1000.0) + " s window, above the rig's max_duty of " +
                             std::to_string(limits.max_duty * 100) + "% (lights.options.safety)");
  }
}

}  // namespace

std::map<std::string, double> PoseTargets(const config::GonioPose& pose) {
  std::map<std::string, double> targets = {{"light_arm", pose.light_arm_deg},
                                           {"camera_arm", pose.camera_arm_deg},
                                           {"sample_rotation", pose.sample_rotation_deg}};
  if (pose.sample_changer_deg) targets["sample_changer"] = *pose.sample_changer_deg;
  return targets;
}

bool PlanOptions::IsValid(std::string* why) const {
  if (!(step_overhead_ms >= 0)) return Refuse(why, "step_overhead_ms must be >= 0");
  if (!(max_led_duty > 0 && max_led_duty <= 1)) return Refuse(why, "max_led_duty must be within (0, 1]");
  return true;
}

RunPlan PlanRun(const config::Recipe& recipe, const config::RigConfig& rig, const std::vector<config::CaptureStep>& steps,
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
  std::map<int, DutyWindow> lit_windows;  // by channel
  double total_ms = 0.0;
  std::map<std::string, double> axes_at;  // every axis starts from its home
  if (rig.motion)
    for (const config::AxisConfig& axis : rig.motion->axes) axes_at[axis.id] = axis.limits.home_deg;
  for (const config::CaptureStep& step : steps) {
    const double exposure_ms = step.exposure_us / 1000.0;
    const double step_start_ms = total_ms;
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
    for (std::size_t channel = 0; channel < step.pattern->levels.size(); ++channel) {
      const double level = step.pattern->levels[channel];
      if (level < 0.0 || level > 1.0)
        plan.errors.push_back("step " + step.label + ": channel " + std::to_string(channel) + " level " +
                              std::to_string(level) + " outside [0, 1]");
      if (level > 0.0) {
        lit_ms[static_cast<int>(channel)] += exposure_ms;
        lit_windows.try_emplace(static_cast<int>(channel), rig.lights.safety.duty_window_ms)
            .first->second.Add(step_start_ms, exposure_ms);
      }
    }
  }
  plan.estimate.duration_s = total_ms / 1000.0;
  if (const config::Recipe::Group* group = config::AdaptivePlanGroup(recipe); group && rig.motion) {
    const config::Recipe::Group::AdaptivePlan& a = *group->adaptive;
    AdaptiveBound bound;
    bound.coarse_poses = static_cast<int>(group->poses.size());
    bound.passes = a.passes;
    bound.added_poses = a.options.added_poses;
    const int poses = a.passes * a.options.added_poses;
    const std::vector<double> exposures =
        group->exposures_us.empty() ? std::vector<double>{recipe.exposure_us.value_or(rig.camera.exposure_us)}
                                    : group->exposures_us;
    bound.max_frames = poses * group->count * static_cast<int>(exposures.size());
    double pose_ms = 0.0;
    for (double exposure_us : exposures) pose_ms += group->count * (exposure_us / 1000.0 + options.step_overhead_ms);
    auto span = [&](auto arm) {
      const auto [lo, hi] = std::minmax_element(group->poses.begin(), group->poses.end(),
                                                [&](const config::GonioPose& x, const config::GonioPose& y) { return arm(x) < arm(y); });
      return lo == group->poses.end() ? 0.0 : arm(*hi) - arm(*lo);
    };
    pose_ms += MoveMs(*rig.motion, {{"light_arm", 0.0}, {"camera_arm", 0.0}},
                      {{"light_arm", span([](const config::GonioPose& p) { return p.light_arm_deg; })},
                       {"camera_arm", span([](const config::GonioPose& p) { return p.camera_arm_deg; })}});
    bound.max_duration_s = poses * pose_ms / 1000.0;
    bound.max_bytes = static_cast<std::uint64_t>(bound.max_frames) * (plan.estimate.bytes_per_frame + 512);
    plan.estimate.bytes += bound.max_bytes;
    plan.adaptive = bound;
  }
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
  CheckLightSafety(rig, lit_windows, &plan);
  if (steps.empty()) plan.warnings.push_back("recipe " + recipe.path + " compiles to no steps");
  for (const config::Recipe::Group& group : recipe.groups)
    for (const std::string& note : group.plan_notes)
      plan.warnings.push_back((group.source ? group.source->file() + ":" + std::to_string(group.source->line()) + ": "
                                            : std::string()) + "pose plan: " + note);
  return plan;
}

nlohmann::json RunPlan::ToJson(const std::vector<config::CaptureStep>& steps, std::size_t max_listed_steps) const {
  nlohmann::json list = nlohmann::json::array();
  const std::size_t listed = std::min(steps.size(), max_listed_steps);
  for (std::size_t i = 0; i < listed; ++i) {
    const config::CaptureStep& step = steps[i];
    nlohmann::json s = {{"index", step.index},
                        {"label", step.label},
                        {"kind", config::CaptureStepKindName(step.kind)},
                        {"group", step.group},
                        {"repeat", step.repeat},
                        {"exposure_us", step.exposure_us},
                        {"gain_db", step.gain_db},
                        {"levels", step.pattern->levels}};
    if (step.pose)
      s["pose"] = {{"light_arm_deg", step.pose->light_arm_deg},
                   {"camera_arm_deg", step.pose->camera_arm_deg},
                   {"sample_rotation_deg", step.pose->sample_rotation_deg}};
    list.push_back(std::move(s));
  }
  nlohmann::json out = {{"ok", ok()},
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
  if (adaptive)
    out["adaptive"] = {{"coarse_poses", adaptive->coarse_poses},   {"passes", adaptive->passes},
                       {"added_poses_per_pass", adaptive->added_poses}, {"max_added_frames", adaptive->max_frames},
                       {"max_added_duration_s", adaptive->max_duration_s}, {"max_added_bytes", adaptive->max_bytes}};
  return out;
}

std::uint64_t PlanMemoryBytes(std::size_t frames, std::size_t channels, std::size_t listed) {
  // A step: the struct and a label too long for the string's own buffer;
  // twice, as a group's steps are built once and then copied into the plan.
  // Their patterns are shared: at most one per LED and group kind. A listed
  // step: its JSON object (a node per key), a number per level, and its text
  // in the answer.
  const std::uint64_t step = sizeof(config::CaptureStep) + 64;
  const std::uint64_t patterns = 4 * (channels + 1) * (8 * channels + 64);
  const std::uint64_t listed_step = 1536 + 24 * channels;
  return 2 * step * frames + patterns + listed_step * listed;
}

struct PlanMemoryBudget::Reservation::Pool {
  std::mutex mutex;
  std::condition_variable freed;
  std::uint64_t capacity = 0;
  std::uint64_t used = 0;

  void Release(std::uint64_t bytes) {
    {
      std::lock_guard lock(mutex);
      used -= std::min(used, bytes);
    }
    freed.notify_all();
  }
};

namespace {

constexpr std::uint64_t kTrimAboveBytes = std::uint64_t{32} << 20;

}  // namespace

PlanMemoryBudget::PlanMemoryBudget(std::uint64_t bytes) : pool_(std::make_shared<Reservation::Pool>()) {
  pool_->capacity = bytes;
}

std::shared_ptr<PlanMemoryBudget::Reservation> PlanMemoryBudget::Reserve(std::uint64_t bytes,
                                                                         std::chrono::milliseconds wait) {
  const std::uint64_t held = std::min(bytes, pool_->capacity);
  std::unique_lock lock(pool_->mutex);
  if (!pool_->freed.wait_for(lock, wait, [&] { return pool_->used + held <= pool_->capacity; })) return nullptr;
  pool_->used += held;
  return std::shared_ptr<Reservation>(new Reservation(pool_, held));
}

void PlanMemoryBudget::Reservation::Shrink(std::uint64_t bytes) {
  if (bytes >= bytes_) return;
  pool_->Release(bytes_ - bytes);
  bytes_ = bytes;
}

PlanMemoryBudget::Reservation::~Reservation() {
  pool_->Release(bytes_);
  // A large plan's memory (or a compilation cut short at a limit) goes back
  // to the system: glibc would keep the freed heap of every thread's arena.
  if (bytes_ >= kTrimAboveBytes) ::malloc_trim(0);
}

std::uint64_t FreeBytes(const std::string& path) {
  fs::path probe = fs::absolute(path);
  while (!probe.empty() && !fs::exists(probe) && probe != probe.parent_path()) probe = probe.parent_path();
  struct statvfs info {};
  if (::statvfs(probe.c_str(), &info) != 0) return 0;
  return static_cast<std::uint64_t>(info.f_bavail) * info.f_frsize;
}

}  // namespace photorig::daemon
