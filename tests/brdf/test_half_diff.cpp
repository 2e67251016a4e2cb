#include "photorig/solvers/brdf/half_diff.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace photorig::solvers::brdf {
namespace {

constexpr double kDeg = M_PI / 180.0;

TEST(HalfDiff, HandComputedInPlaneMirrorConfiguration) {
  // Light at -30 deg and camera at +30 deg in the x-z plane: h is the normal,
  // d is w_i itself, which lies at azimuth pi.
  const Eigen::Vector3d wi(-0.5, 0.0, std::sqrt(3.0) / 2.0), wo(0.5, 0.0, std::sqrt(3.0) / 2.0);
  const HalfDiff a = ToHalfDiff(wi, wo);
  EXPECT_NEAR(a.theta_h, 0.0, 1e-12);
  EXPECT_NEAR(a.theta_d, 30.0 * kDeg, 1e-12);
  EXPECT_NEAR(std::abs(a.phi_d), M_PI, 1e-12);
}

TEST(HalfDiff, HandComputedRetroReflection) {
  // w_i = w_o at 40 deg: h = w_i, so theta_h = 40 deg and theta_d = 0.
  const Eigen::Vector3d w(std::sin(40 * kDeg), 0.0, std::cos(40 * kDeg));
  const HalfDiff a = ToHalfDiff(w, w);
  EXPECT_NEAR(a.theta_h, 40.0 * kDeg, 1e-12);
  EXPECT_NEAR(a.theta_d, 0.0, 1e-7);
}

TEST(HalfDiff, AnglesToDirectionsAndBack) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int k = 0; k < 1000; ++k) {
    const HalfDiff a{(1.0 + 88.0 * u(rng)) * kDeg, (1.0 + 88.0 * u(rng)) * kDeg, (-179.0 + 358.0 * u(rng)) * kDeg};
    const double phi_h = 2.0 * M_PI * u(rng);
    const DirectionPair dirs = FromHalfDiff(a, phi_h);
    EXPECT_NEAR(dirs.wi.norm(), 1.0, 1e-12);
    EXPECT_NEAR(dirs.wo.norm(), 1.0, 1e-12);
    const HalfDiff b = ToHalfDiff(dirs.wi, dirs.wo);
    EXPECT_NEAR(b.theta_h, a.theta_h, 1e-9);
    EXPECT_NEAR(b.theta_d, a.theta_d, 1e-9);
    EXPECT_NEAR(b.phi_d, a.phi_d, 1e-9);
  }
}

TEST(HalfDiff, DirectionsToAnglesAndBack) {
  std::mt19937 rng(11);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int k = 0; k < 1000; ++k) {
    Eigen::Vector3d wi(g(rng), g(rng), std::abs(g(rng)) + 0.1), wo(g(rng), g(rng), std::abs(g(rng)) + 0.1);
    wi.normalize();
    wo.normalize();
    const Eigen::Vector3d h = (wi + wo).normalized();
    const DirectionPair back = FromHalfDiff(ToHalfDiff(wi, wo), std::atan2(h.y(), h.x()));
    EXPECT_LT((back.wi - wi).norm(), 1e-9);
    EXPECT_LT((back.wo - wo).norm(), 1e-9);
  }
}

}  // namespace
}  // namespace photorig::solvers::brdf
