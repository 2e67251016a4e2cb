#include "photorig/solvers/brdf/pose_plan.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace photorig::solvers::brdf {
namespace {

constexpr double kDeg = M_PI / 180.0;

std::string Deg(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.2f", value);
  return text;
}

std::vector<double> Steps(double min, double max, int steps) {
  std::vector<double> values;
  for (int i = 0; i < steps; ++i) values.push_back(steps == 1 ? min : min + (max - min) * i / (steps - 1.0));
  return values;
}

// The move between two poses: the arms move together, so the longer one sets it.
// The sequencer moves one axis at a time (so that the swept paths can be
// checked for separation), so a move takes the sum of the axes' travel.
double MoveDeg(const ArmPose& a, const ArmPose& b) {
  return std::abs(a.light_arm_deg - b.light_arm_deg) + std::abs(a.camera_arm_deg - b.camera_arm_deg) +
         std::abs(a.sample_rotation_deg - b.sample_rotation_deg);
}

// The least distance to `fixed_deg` of an arm sweeping from `from_deg` to `to_deg`.
double SweepClearanceDeg(double from_deg, double to_deg, double fixed_deg) {
  if (std::min(from_deg, to_deg) <= fixed_deg && fixed_deg <= std::max(from_deg, to_deg)) return 0.0;
  return std::min(std::abs(from_deg - fixed_deg), std::abs(to_deg - fixed_deg));
}

}  // namespace

bool SamplingSpec::IsValid(std::string* why) const {
  if (theta_h_steps < 1 || theta_d_steps < 1 || phi_d_steps < 1) {
    *why = "every angle needs at least one step";
    return false;
  }
  if (!(theta_h_min_deg >= 0.0 && theta_h_min_deg <= theta_h_max_deg && theta_h_max_deg <= 90.0) ||
      !(theta_d_min_deg >= 0.0 && theta_d_min_deg <= theta_d_max_deg && theta_d_max_deg <= 90.0)) {
    *why = "theta_h and theta_d ranges must be ordered within [0, 90] deg";
    return false;
  }
  if (!(phi_d_min_deg >= -180.0 && phi_d_min_deg <= phi_d_max_deg && phi_d_max_deg <= 180.0)) {
    *why = "the phi_d range must be ordered within [-180, 180] deg";
    return false;
  }
  return true;
}

std::vector<HalfDiff> UniformHalfDiffGrid(const SamplingSpec& spec) {
  std::vector<HalfDiff> grid;
  for (double th : Steps(spec.theta_h_min_deg, spec.theta_h_max_deg, spec.theta_h_steps))
    for (double td : Steps(spec.theta_d_min_deg, spec.theta_d_max_deg, spec.theta_d_steps))
      for (double pd : Steps(spec.phi_d_min_deg, spec.phi_d_max_deg, spec.phi_d_steps))
        grid.push_back({th * kDeg, td * kDeg, pd * kDeg});
  return grid;
}

bool GonioArms::IsValid(std::string* why) const {
  if (!(light_min_deg < light_max_deg) || !(camera_min_deg < camera_max_deg)) {
    *why = "arm limits must be ordered";
    return false;
  }
  if (!(min_separation_deg >= 0.0)) {
    *why = "min_separation_deg must be non-negative";
    return false;
  }
  if (!(light_home_deg + min_separation_deg <= camera_home_deg)) {
    *why = "the light arm's home must lie at least the separation below the camera arm's";
    return false;
  }
  return true;
}

bool PosePlanOptions::IsValid(std::string* why) const {
  if (!(coplanar_tolerance_deg >= 0.0) || !(std::abs(sample_rotation_deg) <= 180.0)) {
    *why = "coplanar_tolerance_deg must be non-negative and sample_rotation_deg within [-180, 180]";
    return false;
  }
  if (!(grazing_deg > 0.0 && grazing_deg <= 90.0)) {
    *why = "grazing_deg must be within (0, 90]";
    return false;
  }
  return true;
}

bool LightArmFirstKeepsSeparation(const ArmPose& from, const ArmPose& to, double min_separation_deg) {
  return SweepClearanceDeg(from.light_arm_deg, to.light_arm_deg, from.camera_arm_deg) >= min_separation_deg &&
         SweepClearanceDeg(from.camera_arm_deg, to.camera_arm_deg, to.light_arm_deg) >= min_separation_deg;
}

DirectionPair ArmDirections(const ArmPose& pose) {
  // The arm is fixed and the sample turns: in the sample's frame the arm turns back.
  auto direction = [&](double angle_deg) {
    return RotateAbout(Eigen::Vector3d(std::sin(angle_deg * kDeg), 0.0, std::cos(angle_deg * kDeg)),
                       Eigen::Vector3d::UnitZ(), -pose.sample_rotation_deg * kDeg);
  };
  return {direction(pose.light_arm_deg), direction(pose.camera_arm_deg)};
}

PosePlan PlanPoses(const std::vector<HalfDiff>& requested, const GonioArms& arms, const PosePlanOptions& options) {
  core::SolveTimer timer;
  PosePlan plan;
  std::string why;
  if (!arms.IsValid(&why) || !options.IsValid(&why)) {
    plan.End(core::Termination::kInvalidOptions, why);
    return plan;
  }
  timer.SetupDone(&plan);
  std::vector<PlannedPose> reachable;
  for (const HalfDiff& want : requested) {
    auto refuse = [&](std::string reason) { plan.refused.push_back({want, std::move(reason)}); };
    const DirectionPair dirs = FromHalfDiff(want);
    if (!dirs.wi.allFinite() || !dirs.wo.allFinite()) {
      refuse("not a configuration");
      continue;
    }
    if (dirs.wi.z() <= 0.0 || dirs.wo.z() <= 0.0) {
      refuse("below the horizon (theta_i or theta_o >= 90 deg)");
      continue;
    }
    // The plane through the normal that holds w_i (or w_o when w_i is the normal).
    Eigen::Vector2d axis = dirs.wi.head<2>();
    if (axis.norm() < 1e-12) axis = dirs.wo.head<2>();
    axis = axis.norm() < 1e-12 ? Eigen::Vector2d::UnitX() : axis.normalized();
    const Eigen::Vector2d across(-axis.y(), axis.x());
    const double off_plane_deg =
        std::max(std::abs(std::asin(std::clamp(dirs.wi.head<2>().dot(across), -1.0, 1.0))),
                 std::abs(std::asin(std::clamp(dirs.wo.head<2>().dot(across), -1.0, 1.0)))) / kDeg;
    if (off_plane_deg > options.coplanar_tolerance_deg) {
      refuse("out of the arms' plane by " + Deg(off_plane_deg) +
             " deg: two arms in one plane reach phi_d = 0 or 180 deg (or theta_h = 0) only");
      continue;
    }
    // Signed angles in that plane; the light goes on the camera's negative side.
    double light = std::atan2(dirs.wi.head<2>().dot(axis), dirs.wi.z()) / kDeg;
    double camera = std::atan2(dirs.wo.head<2>().dot(axis), dirs.wo.z()) / kDeg;
    if (light > camera) {
      light = -light;
      camera = -camera;
    }
    if (light < arms.light_min_deg || light > arms.light_max_deg) {
      refuse("light arm at " + Deg(light) + " deg, beyond its limits [" + Deg(arms.light_min_deg) + ", " +
             Deg(arms.light_max_deg) + "]");
      continue;
    }
    if (camera < arms.camera_min_deg || camera > arms.camera_max_deg) {
      refuse("camera arm at " + Deg(camera) + " deg, beyond its limits [" + Deg(arms.camera_min_deg) + ", " +
             Deg(arms.camera_max_deg) + "]");
      continue;
    }
    if (camera - light < arms.min_separation_deg) {
      refuse("arms " + Deg(camera - light) + " deg apart, closer than " + Deg(arms.min_separation_deg));
      continue;
    }
    PlannedPose planned{want, {light, camera, options.sample_rotation_deg}};
    planned.grazing = std::max(std::abs(light), std::abs(camera)) > options.grazing_deg;
    reachable.push_back(planned);
  }
  const ArmPose home =
      options.start.value_or(ArmPose{arms.light_home_deg, arms.camera_home_deg, options.sample_rotation_deg});
  ArmPose at = home;
  for (const PlannedPose& p : reachable) {
    plan.requested_order_move_deg += MoveDeg(at, p.arms);
    at = p.arms;
  }
  // Greedy nearest neighbour: O(n^2), fine for the few thousand poses a run can afford.
  at = home;
  std::vector<bool> used(reachable.size(), false);
  for (std::size_t k = 0; k < reachable.size(); ++k) {
    std::size_t next = 0;
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < reachable.size(); ++i)
      if (!used[i] && MoveDeg(at, reachable[i].arms) < best) {
        best = MoveDeg(at, reachable[i].arms);
        next = i;
      }
    used[next] = true;
    plan.planned_move_deg += best;
    PlannedPose pose = reachable[next];
    pose.light_arm_first = LightArmFirstKeepsSeparation(at, pose.arms, arms.min_separation_deg);
    plan.grazing += pose.grazing;
    at = pose.arms;
    plan.poses.push_back(pose);
  }
  if (plan.poses.empty()) {
    plan.End(core::Termination::kFailure, "none of the " + std::to_string(requested.size()) +
                                        " requested configurations is reachable by the arms");
  } else {
    plan.termination = core::Termination::kSuccess;
    if (!plan.refused.empty())
      plan.message = std::to_string(plan.refused.size()) + " of " + std::to_string(requested.size()) +
                     " configurations refused (first: " + plan.refused.front().reason + ")";
    if (plan.grazing > 0)
      plan.message += std::string(plan.message.empty() ? "" : "; ") + std::to_string(plan.grazing) +
                      " poses grazing (an arm beyond " + Deg(options.grazing_deg) + " deg)";
  }
  timer.Finish(&plan);
  return plan;
}

bool AdaptiveOptions::IsValid(std::string* why) const {
  if (added_poses < 1) {
    *why = "added_poses must be at least 1";
    return false;
  }
  if (!(min_interval_deg > 0.0) || !(value_floor > 0.0)) {
    *why = "min_interval_deg and value_floor must be positive";
    return false;
  }
  return true;
}

AdaptiveProposal ProposeDenserPoses(const std::vector<PlanSample>& measured, const GonioArms& arms,
                                    const PosePlanOptions& plan_options, const AdaptiveOptions& options) {
  core::SolveTimer timer;
  AdaptiveProposal proposal;
  std::string why;
  if (!options.IsValid(&why) || !arms.IsValid(&why) || !plan_options.IsValid(&why)) {
    proposal.End(core::Termination::kInvalidOptions, why);
    return proposal;
  }
  for (std::size_t i = 0; i < measured.size(); ++i)
    if (!std::isfinite(measured[i].value)) {
      proposal.End(core::Termination::kInvalidInput, "sample " + std::to_string(i) + " has a value that is not finite");
      return proposal;
    }
  timer.SetupDone(&proposal);
  struct Interval {
    HalfDiff midpoint;
    double score;
  };
  std::vector<Interval> intervals;
  // Angles equal within this count as the same row of the grid.
  constexpr double kSame = 1e-9;
  // Split along theta_h (axis 0) and theta_d (axis 1): neighbours share the other two angles.
  for (int axis = 0; axis < 2; ++axis) {
    auto along = [axis](const HalfDiff& a) { return axis == 0 ? a.theta_h : a.theta_d; };
    auto across = [axis](const HalfDiff& a) { return axis == 0 ? a.theta_d : a.theta_h; };
    std::vector<std::size_t> order(measured.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      const HalfDiff &x = measured[a].at, &y = measured[b].at;
      if (std::abs(across(x) - across(y)) > kSame) return across(x) < across(y);
      if (std::abs(x.phi_d - y.phi_d) > kSame) return x.phi_d < y.phi_d;
      return along(x) < along(y);
    });
    for (std::size_t k = 1; k < order.size(); ++k) {
      const PlanSample &a = measured[order[k - 1]], &b = measured[order[k]];
      if (std::abs(across(a.at) - across(b.at)) > kSame || std::abs(a.at.phi_d - b.at.phi_d) > kSame) continue;
      if (along(b.at) - along(a.at) < 2.0 * options.min_interval_deg * kDeg) continue;
      HalfDiff mid = a.at;
      (axis == 0 ? mid.theta_h : mid.theta_d) = 0.5 * (along(a.at) + along(b.at));
      // A value below zero is noise about a dark one: it counts as zero.
      intervals.push_back({mid, std::abs(std::log(std::max(a.value, 0.0) + options.value_floor) -
                                         std::log(std::max(b.value, 0.0) + options.value_floor))});
    }
  }
  std::stable_sort(intervals.begin(), intervals.end(),
                   [](const Interval& a, const Interval& b) { return a.score > b.score; });
  for (const Interval& interval : intervals) {
    if (static_cast<int>(proposal.proposed.size()) == options.added_poses) break;
    if (!PlanPoses({interval.midpoint}, arms, plan_options).IsSolutionUsable()) {
      ++proposal.unreachable;
      continue;
    }
    proposal.proposed.push_back(interval.midpoint);
    proposal.score.push_back(interval.score);
  }
  if (proposal.proposed.empty()) {
    proposal.End(core::Termination::kFailure, "no interval between " + std::to_string(measured.size()) +
                                            " samples splits into a configuration the arms reach");
    return proposal;
  }
  proposal.plan = PlanPoses(proposal.proposed, arms, plan_options);
  proposal.termination = core::Termination::kSuccess;
  timer.Finish(&proposal);
  return proposal;
}

}  // namespace photorig::solvers::brdf
