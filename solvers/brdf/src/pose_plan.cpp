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
double MoveDeg(const ArmPose& a, const ArmPose& b) {
  return std::max(std::abs(a.light_arm_deg - b.light_arm_deg), std::abs(a.camera_arm_deg - b.camera_arm_deg));
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
  return true;
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
  SolveTimer timer;
  PosePlan plan;
  std::string why;
  if (!arms.IsValid(&why) || !options.IsValid(&why)) {
    plan.End(Termination::kInvalidOptions, why);
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
    reachable.push_back({want, {light, camera, options.sample_rotation_deg}});
  }
  const ArmPose home{arms.light_home_deg, arms.camera_home_deg, options.sample_rotation_deg};
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
    at = reachable[next].arms;
    plan.poses.push_back(reachable[next]);
  }
  if (plan.poses.empty()) {
    plan.End(Termination::kFailure, "none of the " + std::to_string(requested.size()) +
                                        " requested configurations is reachable by the arms");
  } else {
    plan.termination = Termination::kSuccess;
    if (!plan.refused.empty())
      plan.message = std::to_string(plan.refused.size()) + " of " + std::to_string(requested.size()) +
                     " configurations refused (first: " + plan.refused.front().reason + ")";
  }
  timer.Finish(&plan);
  return plan;
}

}  // namespace photorig::solvers::brdf
