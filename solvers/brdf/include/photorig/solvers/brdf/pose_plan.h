#pragma once
// Gonioreflectometer pose plans: a sampling spec uniform in Rusinkiewicz's
// (theta_h, theta_d, phi_d), mapped to (w_i, w_o) in the sample frame and then
// to the angles of a light arm and a camera arm that swing in one plane
// through the sample normal, and a turntable turning the sample about it
// (the geometry of config/rigs/sim-gonio.yaml: an arm at t points along
// (sin t, 0, cos t), 0 = on the normal).
//
// Two arms in one plane reach only configurations whose w_i, w_o and normal
// are coplanar: phi_d = 0 or 180 deg (in-plane), or theta_h = 0. The plan
// refuses the rest with the reason, and every pose the arms' limits or
// separation forbid. The light arm always stays on the negative side of the
// camera arm, as their homes are, so the arms never have to pass each other.
// The BRDF is taken isotropic: the turntable stays where the options say.

#include "photorig/solvers/brdf/half_diff.h"
#include "photorig/solvers/summary.h"

#include <string>
#include <vector>

namespace photorig::solvers::brdf {

// A grid uniform in each angle, both ends included (one step: the minimum).
struct SamplingSpec {
  double theta_h_min_deg = 0.0, theta_h_max_deg = 60.0;
  int theta_h_steps = 13;
  double theta_d_min_deg = 10.0, theta_d_max_deg = 70.0;
  int theta_d_steps = 13;
  double phi_d_min_deg = 0.0, phi_d_max_deg = 0.0;
  int phi_d_steps = 1;

  bool IsValid(std::string* why) const;
};

// theta_h slowest, phi_d fastest.
std::vector<HalfDiff> UniformHalfDiffGrid(const SamplingSpec& spec);

// The arms' reach (defaults: config/rigs/sim-gonio.yaml).
struct GonioArms {
  double light_min_deg = -85.0, light_max_deg = 85.0;
  double camera_min_deg = -85.0, camera_max_deg = 85.0;
  double min_separation_deg = 15.0;  // the lamp housing and the camera collide closer than this
  double light_home_deg = -60.0, camera_home_deg = 60.0;

  bool IsValid(std::string* why) const;
};

struct ArmPose {
  double light_arm_deg = 0.0;
  double camera_arm_deg = 0.0;
  double sample_rotation_deg = 0.0;
};

// (w_i, w_o) in the sample frame for the arms at `pose`.
DirectionPair ArmDirections(const ArmPose& pose);

struct PosePlanOptions {
  double sample_rotation_deg = 0.0;  // where the turntable stays
  // How far (deg) w_i, w_o may lie from one plane through the normal and still
  // count as in the arms' plane.
  double coplanar_tolerance_deg = 0.01;

  bool IsValid(std::string* why) const;
};

struct PlannedPose {
  HalfDiff requested;
  ArmPose arms;
};

struct RefusedPose {
  HalfDiff requested;
  std::string reason;
};

struct PosePlan : Summary {
  std::vector<PlannedPose> poses;    // in the order to visit them
  std::vector<RefusedPose> refused;  // with why
  // Sum over the moves from home through every pose of the larger arm move
  // (the arms move together), in the requested order and in the plan's.
  double requested_order_move_deg = 0.0;
  double planned_move_deg = 0.0;
};

// Maps every requested configuration to arm angles, refuses the unreachable
// ones, and orders the rest greedily (nearest next pose from home) to keep
// moves short. kFailure when no pose is reachable.
PosePlan PlanPoses(const std::vector<HalfDiff>& requested, const GonioArms& arms, const PosePlanOptions& options = {});

}  // namespace photorig::solvers::brdf
