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
#include "photorig/solvers/core/summary.h"

#include <optional>
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
  // Where the arms stand before the first move (a later pass of an adaptive
  // plan starts where the previous one ended). Unset: at their homes.
  std::optional<ArmPose> start;
  // A planned pose with theta_i or theta_o beyond this is counted as grazing
  // (flagged, not weighted): there the sample's footprint stretches as
  // 1 / cos, a small arm error moves the value most, and the cosine makes the
  // cosine-weighted signal small.
  double grazing_deg = 80.0;
  // How far (deg) w_i, w_o may lie from one plane through the normal and still
  // count as in the arms' plane.
  double coplanar_tolerance_deg = 0.01;

  bool IsValid(std::string* why) const;
};

struct PlannedPose {
  HalfDiff requested;
  ArmPose arms;
  // The move here from the pose before runs one arm at a time (as the
  // daemon's Goniometer does): light arm first when the light arm's sweep
  // keeps the separation from the camera arm still where it was, else camera
  // arm first. For two arms that stay on their own sides one of the two
  // orders always keeps the separation throughout.
  bool light_arm_first = true;
  bool grazing = false;  // theta_i or theta_o beyond PosePlanOptions::grazing_deg
};

struct RefusedPose {
  HalfDiff requested;
  std::string reason;
};

struct PosePlan : core::Summary {
  std::vector<PlannedPose> poses;    // in the order to visit them
  std::vector<RefusedPose> refused;  // with why
  // Axis travel from home through every pose (each move: the light arm's,
  // the camera arm's and the rotation's travel added, as the axes move one at
  // a time), in the requested order and in the plan's.
  double requested_order_move_deg = 0.0;
  double planned_move_deg = 0.0;
  int grazing = 0;  // planned poses flagged grazing
};

// Maps every requested configuration to arm angles, refuses the unreachable
// ones, and orders the rest greedily (nearest next pose from home) to keep
// moves short. kFailure when no pose is reachable.
PosePlan PlanPoses(const std::vector<HalfDiff>& requested, const GonioArms& arms, const PosePlanOptions& options = {});

// Whether moving the light arm first from `from` to `to` (then the camera arm)
// keeps the arms at least `min_separation_deg` apart at every point of both
// sweeps; false says the camera arm must go first.
bool LightArmFirstKeepsSeparation(const ArmPose& from, const ArmPose& to, double min_separation_deg);

// Adaptive plans: after a coarse pass, propose the configurations that split
// the intervals between measured neighbours where the measured value changes
// most. Neighbours share two of (theta_h, theta_d, phi_d) and are adjacent in
// the third among the samples (theta_h and theta_d are split; phi_d is not, as
// two in-plane arms reach phi_d = 0 only). The score of an interval is
// |log(v_a + floor) - log(v_b + floor)|: a lobe's flanks, where a uniform grid
// loses most, score highest.
struct PlanSample {
  HalfDiff at;
  double value = 0.0;  // the measured f_r (1/sr; e.g. the channels' mean); below 0 (noise) counts as 0
};

struct AdaptiveOptions {
  int added_poses = 16;          // how many reachable configurations to propose
  double min_interval_deg = 0.5;  // intervals narrower than this are not split
  // Added to every value before the log (1/sr): keeps the noise of values near
  // zero from driving the refinement.
  double value_floor = 1e-3;

  bool IsValid(std::string* why) const;
};

struct AdaptiveProposal : core::Summary {
  std::vector<HalfDiff> proposed;  // highest score first, all reachable
  std::vector<double> score;       // of each proposed configuration's interval
  PosePlan plan;                   // `proposed` planned from PosePlanOptions::start
  int unreachable = 0;             // midpoints of high-scoring intervals the arms cannot reach
};

// kInvalidInput for a sample with a non-finite value; kFailure when
// no interval can be split into a reachable configuration.
AdaptiveProposal ProposeDenserPoses(const std::vector<PlanSample>& measured, const GonioArms& arms,
                                    const PosePlanOptions& plan_options = {}, const AdaptiveOptions& options = {});

}  // namespace photorig::solvers::brdf
