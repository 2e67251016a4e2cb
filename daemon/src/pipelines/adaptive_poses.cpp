#include "photorig/daemon/pipelines/adaptive_poses.h"

#include "photorig/daemon/pipelines/brdf_measurement.h"
#include "photorig/solvers/brdf/half_diff.h"
#include "photorig/solvers/brdf/pose_plan.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <set>

namespace photorig::daemon {
namespace brdf = solvers::brdf;

nlohmann::json AdaptivePassReport::ToJson() const {
  nlohmann::json out = {{"pass", pass},
                        {"samples", samples},
                        {"poses_added", poses_added},
                        {"frames_added", frames_added},
                        {"unreachable", unreachable}};
  if (!stopped.empty()) out["stopped"] = stopped;
  return out;
}

AdaptivePoses::AdaptivePoses(const config::Recipe& recipe, const config::Recipe::Group& group, const config::RigConfig& rig)
    : recipe_(recipe), group_(group), rig_(rig) {}

CaptureOptions::AddedSteps AdaptivePoses::NextPass(const std::vector<config::CaptureStep>& steps, std::size_t ended,
                                                   const RunWriter& writer) {
  const config::Recipe::Group::AdaptivePlan& plan = *group_.adaptive;
  const config::CaptureStep& last = steps[ended];
  AdaptivePassReport report;
  report.pass = last.pass + 1;
  if (report.pass > plan.passes) return {};
  // Only the frames of the steps up to here: in a resumed run later ones may be stored already.
  std::set<int> before;
  for (std::size_t k = 0; k <= ended; ++k) before.insert(steps[k].index);
  RunManifest partial = writer.manifest();
  std::erase_if(partial.frames, [&](const FrameRecord& r) { return !before.count(r.index); });
  const BrdfMeasurement measured = MeasureBrdf(writer.directory(), partial);
  auto end_plan = [&](std::string why) {
    report.stopped = std::move(why);
    spdlog::info("adaptive pass {}: {}", report.pass, report.stopped);
    passes_.push_back(report);
    return CaptureOptions::AddedSteps{{}, "adaptive pass " + std::to_string(report.pass) + " of " +
                                              std::to_string(plan.passes) + ": none added: " + passes_.back().stopped};
  };
  if (!measured.IsSolutionUsable()) return end_plan("the poses so far could not be measured: " + measured.message);

  std::vector<brdf::PlanSample> samples, on_peak;
  std::set<double> rows;  // the phi_d of the samples off the peak
  for (std::size_t k = 0; k < measured.samples.size(); ++k) {
    brdf::HalfDiff at = brdf::ToHalfDiff(measured.samples[k].wi, measured.samples[k].wo);
    // In the arms' plane phi_d is 0 or pi; rounding must not split one grid row in two.
    if (std::abs(at.phi_d) < 1e-9) at.phi_d = 0.0;
    if (std::abs(std::abs(at.phi_d) - M_PI) < 1e-9) at.phi_d = M_PI;
    (at.theta_h < 1e-9 ? on_peak : samples).push_back({at, measured.samples[k].value.mean()});
    if (at.theta_h >= 1e-9) rows.insert(at.phi_d);
  }
  // On the specular peak (theta_h = 0) phi_d is free: the sample ends every
  // row, so the lobe's steepest interval, from the peak out, can be split.
  for (brdf::PlanSample peak : on_peak)
    for (double phi_d : rows.empty() ? std::set<double>{peak.at.phi_d} : rows) {
      peak.at.phi_d = phi_d;
      samples.push_back(peak);
    }
  report.samples = static_cast<int>(samples.size());
  brdf::PosePlanOptions plan_options = plan.plan;
  // From where the arms stand after the pass: the planned pose, so a resumed run plans the same order.
  if (last.pose) plan_options.start = brdf::ArmPose{last.pose->light_arm_deg, last.pose->camera_arm_deg,
                                                     last.pose->sample_rotation_deg};
  const brdf::AdaptiveProposal proposal =
      brdf::ProposeDenserPoses(samples, *config::GonioArmsOf(*rig_.motion), plan_options, plan.options);
  report.unreachable = proposal.unreachable;
  if (proposal.termination == solvers::core::Termination::kFailure)
    return end_plan("nothing left to split (" + proposal.message + ")");
  if (!proposal.IsSolutionUsable()) return end_plan("no poses proposed: " + proposal.message);

  std::vector<config::GonioPose> poses;
  for (const brdf::PlannedPose& p : proposal.plan.poses)
    poses.push_back({p.arms.light_arm_deg, p.arms.camera_arm_deg, p.arms.sample_rotation_deg, std::nullopt});
  int next_index = 0;
  for (const config::CaptureStep& step : steps) next_index = std::max(next_index, step.index + 1);
  CaptureOptions::AddedSteps added;
  added.steps = CompileAdaptivePass(recipe_, group_, rig_, poses, next_index, report.pass);
  report.poses_added = static_cast<int>(poses.size());
  report.frames_added = static_cast<int>(added.steps.size());
  if (report.poses_added < plan.options.added_poses)
    report.stopped = "only " + std::to_string(report.poses_added) + " of " + std::to_string(plan.options.added_poses) +
                     " intervals split into configurations the arms reach (" + std::to_string(report.unreachable) +
                     " midpoints unreachable, the rest narrower than min_interval_deg)";
  added.detail = "adaptive pass " + std::to_string(report.pass) + " of " + std::to_string(plan.passes) + ": " +
                 std::to_string(report.poses_added) + " poses added (" + std::to_string(report.frames_added) +
                 " frames) from " + std::to_string(report.samples) + " samples";
  spdlog::info("{}", added.detail);
  passes_.push_back(std::move(report));
  return added;
}

}  // namespace photorig::daemon
