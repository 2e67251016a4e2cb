#include "photorig/solvers/brdf/pose_plan.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <optional>
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
  ASSERT_EQ(plan.termination, core::Termination::kSuccess) << plan.message;
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

  EXPECT_EQ(PlanPoses({requested[0]}, GonioArms()).termination, core::Termination::kFailure);
  GonioArms crossed;
  crossed.light_home_deg = 60.0;
  EXPECT_EQ(PlanPoses(requested, crossed).termination, core::Termination::kInvalidOptions);
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

TEST(PosePlan, EveryMoveHasAnOrderThatKeepsTheArmsApart) {
  // From home, through a shuffled grid and a plan started elsewhere: the arm
  // that moves first is the one whose sweep clears the other, checked here
  // point by point.
  std::vector<HalfDiff> requested = UniformHalfDiffGrid(SamplingSpec());
  std::shuffle(requested.begin(), requested.end(), std::mt19937(7));
  const GonioArms arms;
  int camera_first = 0;
  for (const std::optional<ArmPose>& start : {std::optional<ArmPose>(), std::optional<ArmPose>(ArmPose{-5, 10, 0}),
                                              std::optional<ArmPose>(ArmPose{-70, -50, 0})}) {
    PosePlanOptions options;
    options.start = start;
    const PosePlan plan = PlanPoses(requested, arms, options);
    ASSERT_TRUE(plan.IsSolutionUsable());
    ArmPose at = start.value_or(ArmPose{arms.light_home_deg, arms.camera_home_deg, 0.0});
    for (const PlannedPose& p : plan.poses) {
      const ArmPose& to = p.arms;
      camera_first += !p.light_arm_first;
      for (int k = 0; k <= 100; ++k) {
        const double t = k / 100.0;
        const double light_sweep = at.light_arm_deg + t * (to.light_arm_deg - at.light_arm_deg);
        const double camera_sweep = at.camera_arm_deg + t * (to.camera_arm_deg - at.camera_arm_deg);
        const double first = p.light_arm_first ? at.camera_arm_deg - light_sweep : camera_sweep - at.light_arm_deg;
        const double second = p.light_arm_first ? camera_sweep - to.light_arm_deg : to.camera_arm_deg - light_sweep;
        ASSERT_GE(first, arms.min_separation_deg - 1e-9);
        ASSERT_GE(second, arms.min_separation_deg - 1e-9);
      }
      at = to;
    }
  }
  EXPECT_GT(camera_first, 0);  // both orders were needed (from the arms below the first pose, at least)
  // Light first is wrong when the light arm would sweep into the camera arm's place.
  EXPECT_FALSE(LightArmFirstKeepsSeparation({-60, -45, 0}, {-20, -5, 0}, 15.0));
  EXPECT_TRUE(LightArmFirstKeepsSeparation({-20, -5, 0}, {-60, -45, 0}, 15.0));
}

TEST(PosePlan, GrazingPosesAreFlagged) {
  const std::vector<HalfDiff> requested = {{10 * kDeg, 72 * kDeg, 0.0}, {10 * kDeg, 30 * kDeg, 0.0}};
  const PosePlan plan = PlanPoses(requested, GonioArms());
  ASSERT_EQ(plan.poses.size(), 2u);
  EXPECT_EQ(plan.grazing, 1);  // light arm at -82 deg
  for (const PlannedPose& p : plan.poses) EXPECT_EQ(p.grazing, p.requested.theta_d > 70 * kDeg);
  EXPECT_NE(plan.message.find("1 poses grazing (an arm beyond 80.00 deg)"), std::string::npos) << plan.message;
}

TEST(AdaptivePlan, SplitsWhereTheValueChangesMost) {
  // A 5 x 5 grid in (theta_h, theta_d) whose value drops sharply between
  // theta_h = 10 and 20 deg, and a little between 20 and 30.
  std::vector<PlanSample> measured;
  for (double th : {0.0, 10.0, 20.0, 30.0, 40.0})
    for (double td : {10.0, 20.0, 30.0, 40.0, 44.0})
      measured.push_back({{th * kDeg, td * kDeg, 0.0}, th <= 10.0 ? 10.0 : th <= 20.0 ? 0.1 : 0.05});
  AdaptiveOptions options;
  options.added_poses = 5;
  const AdaptiveProposal proposal = ProposeDenserPoses(measured, GonioArms(), {}, options);
  ASSERT_TRUE(proposal.IsSolutionUsable()) << proposal.message;
  ASSERT_EQ(proposal.proposed.size(), 5u);
  // The five rows' (10, 20) intervals, at theta_h = 15 deg; but theta_h 15 +
  // theta_d 44 = 59 is reachable, so all five.
  for (const HalfDiff& p : proposal.proposed) EXPECT_NEAR(p.theta_h, 15 * kDeg, 1e-12);
  EXPECT_NEAR(proposal.score[0], std::log(10.001 / 0.101), 1e-9);
  EXPECT_EQ(proposal.plan.poses.size(), 5u);

  // Asking more: next the (20, 30) intervals, at log(0.101 / 0.051).
  options.added_poses = 10;
  const AdaptiveProposal more = ProposeDenserPoses(measured, GonioArms(), {}, options);
  ASSERT_EQ(more.proposed.size(), 10u);
  for (int i = 5; i < 10; ++i) EXPECT_NEAR(more.proposed[i].theta_h, 25 * kDeg, 1e-12);

  // Intervals the arms cannot reach are skipped and counted: theta_h + theta_d beyond 85 deg.
  GonioArms short_arms;
  short_arms.light_min_deg = -55.0;
  short_arms.camera_max_deg = 55.0;
  options.added_poses = 5;
  const AdaptiveProposal reachable = ProposeDenserPoses(measured, short_arms, {}, options);
  ASSERT_TRUE(reachable.IsSolutionUsable());
  EXPECT_GT(reachable.unreachable, 0);
  for (const HalfDiff& p : reachable.proposed) EXPECT_LE(p.theta_h + p.theta_d, 55 * kDeg + 1e-9);
}

TEST(AdaptivePlan, RefusesBadSamplesAndStopsAtTheFinestInterval) {
  std::vector<PlanSample> measured = {{{0.0, 20 * kDeg, 0.0}, 1.0}, {{0.8 * kDeg, 20 * kDeg, 0.0}, 0.1}};
  AdaptiveOptions options;
  EXPECT_EQ(ProposeDenserPoses(measured, GonioArms(), {}, options).termination, core::Termination::kFailure);  // 0.8 < 2 x 0.5 deg
  options.min_interval_deg = 0.25;
  const AdaptiveProposal split = ProposeDenserPoses(measured, GonioArms(), {}, options);
  ASSERT_EQ(split.proposed.size(), 1u);
  EXPECT_NEAR(split.proposed[0].theta_h, 0.4 * kDeg, 1e-12);
  measured[1].value = std::nan("");
  const AdaptiveProposal bad = ProposeDenserPoses(measured, GonioArms(), {}, options);
  EXPECT_EQ(bad.termination, core::Termination::kInvalidInput);
  EXPECT_NE(bad.message.find("sample 1"), std::string::npos) << bad.message;
  options.added_poses = 0;
  EXPECT_EQ(ProposeDenserPoses(measured, GonioArms(), {}, options).termination, core::Termination::kInvalidOptions);
}

}  // namespace
}  // namespace photorig::solvers::brdf
