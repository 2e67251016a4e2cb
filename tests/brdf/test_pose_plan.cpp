#include "photorig/solvers/brdf/pose_plan.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

namespace photorig::solvers::brdf {
namespace {

constexpr double kDeg = M_PI / 180.0;

TEST(ArmDirections, FollowTheSimulatedRigsConvention) {
  // config/rigs/sim-gonio.yaml: an arm at t points along (sin t, 0, cos t).
  const DirectionPair d = ArmDirections({-30.0, 30.0, 0.0});
  EXPECT_LT((d.wi - Eigen::Vector3d(-0.5, 0.0, std::sqrt(0.75))).norm(), 1e-12);
  EXPECT_LT((d.wo - Eigen::Vector3d(0.5, 0.0, std::sqrt(0.75))).norm(), 1e-12);
  // A quarter turn of the sample turns the arms by minus a quarter in its frame.
  const DirectionPair r = ArmDirections({0.0, 90.0, 90.0});
  EXPECT_LT((r.wo - Eigen::Vector3d(0.0, -1.0, 0.0)).norm(), 1e-12);
}

TEST(PosePlan, ArmsGiveBackTheRequestedHalfDiffAngles) {
  SamplingSpec spec;
  spec.phi_d_max_deg = 180.0;
  spec.phi_d_steps = 2;  // in-plane both ways round: 0 and 180 deg
  const std::vector<HalfDiff> requested = UniformHalfDiffGrid(spec);
  ASSERT_EQ(requested.size(), 13u * 13u * 2u);
  const GonioArms arms;
  const PosePlan plan = PlanPoses(requested, arms);
  ASSERT_EQ(plan.termination, Termination::kSuccess) << plan.message;
  EXPECT_EQ(plan.poses.size() + plan.refused.size(), requested.size());
  EXPECT_GT(plan.poses.size(), requested.size() / 2);
  for (const PlannedPose& p : plan.poses) {
    EXPECT_GE(p.arms.light_arm_deg, arms.light_min_deg);
    EXPECT_LE(p.arms.camera_arm_deg, arms.camera_max_deg);
    EXPECT_GE(p.arms.camera_arm_deg - p.arms.light_arm_deg, arms.min_separation_deg);
    const DirectionPair d = ArmDirections(p.arms);
    const HalfDiff got = ToHalfDiff(d.wi, d.wo);
    EXPECT_NEAR(got.theta_h, p.requested.theta_h, 1e-9);
    EXPECT_NEAR(got.theta_d, p.requested.theta_d, 1e-9);
    // phi_d is defined up to reciprocity (mod pi), and meaningless at theta_h = 0
    // where every phi_d is one configuration turned about the normal.
    if (p.requested.theta_h > 1e-9) {
      EXPECT_NEAR(std::sin(got.phi_d - p.requested.phi_d), 0.0, 1e-9);
    }
  }
  // Every refusal has a reason the arms explain: too close, beyond a limit or below the horizon.
  for (const RefusedPose& r : plan.refused) {
    const bool close = r.requested.theta_d < 7.5 * kDeg - 1e-12;
    const bool far = r.requested.theta_h + r.requested.theta_d > 85.0 * kDeg + 1e-12;
    EXPECT_TRUE(close || far) << r.reason;
    EXPECT_TRUE(r.reason.find("apart") != std::string::npos || r.reason.find("limits") != std::string::npos ||
                r.reason.find("horizon") != std::string::npos)
        << r.reason;
  }
}

TEST(PosePlan, RefusesWhatTwoArmsInOnePlaneCannotReach) {
  const std::vector<HalfDiff> requested = {
      {30 * kDeg, 30 * kDeg, 90 * kDeg},  // out of the plane
      {20 * kDeg, 5 * kDeg, 0.0},         // arms 10 deg apart
      {45 * kDeg, 42 * kDeg, 0.0},        // an arm at 87 deg
      {0.0, 30 * kDeg, 60 * kDeg},        // theta_h = 0: in a plane through the normal whatever phi_d
  };
  const PosePlan plan = PlanPoses(requested, GonioArms());
  ASSERT_EQ(plan.refused.size(), 3u);
  EXPECT_NE(plan.refused[0].reason.find("plane"), std::string::npos) << plan.refused[0].reason;
  EXPECT_NE(plan.refused[1].reason.find("10.00 deg apart"), std::string::npos) << plan.refused[1].reason;
  EXPECT_NE(plan.refused[2].reason.find("arm at -87.00 deg, beyond its limits"), std::string::npos) << plan.refused[2].reason;
  ASSERT_EQ(plan.poses.size(), 1u);
  EXPECT_NEAR(plan.poses[0].arms.light_arm_deg, -30.0, 1e-9);
  EXPECT_NEAR(plan.poses[0].arms.camera_arm_deg, 30.0, 1e-9);

  EXPECT_EQ(PlanPoses({requested[0]}, GonioArms()).termination, Termination::kFailure);
  GonioArms crossed;
  crossed.light_home_deg = 60.0;
  EXPECT_EQ(PlanPoses(requested, crossed).termination, Termination::kInvalidOptions);
}

TEST(PosePlan, OrderKeepsMovesShort) {
  std::vector<HalfDiff> requested = UniformHalfDiffGrid(SamplingSpec());
  std::shuffle(requested.begin(), requested.end(), std::mt19937(5));
  const PosePlan plan = PlanPoses(requested, GonioArms());
  ASSERT_TRUE(plan.IsSolutionUsable());
  // A shuffled grid crosses the arms' range again and again; the greedy order
  // walks it mostly a grid step at a time.
  EXPECT_LT(plan.planned_move_deg, 0.25 * plan.requested_order_move_deg)
      << plan.planned_move_deg << " vs " << plan.requested_order_move_deg;
}

}  // namespace
}  // namespace photorig::solvers::brdf
