#include "photorig/solvers/tomography/held_out.h"

#include "slice_problem.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

namespace photorig::solvers::tomography {
namespace {

using testing_support::SliceProblem;

// The held-out residual, without the ground truth, ranks what the ground
// truth ranks: the true centre of rotation below a wrong one, and it sits
// above the noise floor it reports.
TEST(HeldOut, TheResidualOfTheOddViewsRanksTheTrueCentreFirst) {
  SliceProblem problem(64, 64, 180.0, 0.75);
  Absorbance data = problem.Exact();
  const float sigma_b = 0.01f * data.b.maxCoeff();
  std::mt19937 rng(2);
  std::normal_distribution<float> gauss(0.0f, sigma_b);
  for (auto& v : data.b) v += gauss(rng);
  data.variance.setConstant(data.b.size(), sigma_b * sigma_b);
  HeldOutOptions options;
  options.reconstruct.method = Method::kSart;
  options.reconstruct.discrepancy_factor = 1.2;
  Geometry geometry = problem.geometry;
  const HeldOutSummary right = HeldOutResidual(problem.grid, geometry, data, options);
  ASSERT_TRUE(right.IsSolutionUsable()) << right.message;
  EXPECT_EQ(right.fit_views, 32);
  EXPECT_EQ(right.held_out_views, 32);
  EXPECT_GT(right.noise_floor, 0.0);
  EXPECT_GT(right.relative_residual, right.noise_floor);
  geometry.cor_offset_mm = 0.0;
  const HeldOutSummary wrong = HeldOutResidual(problem.grid, geometry, data, options);
  ASSERT_TRUE(wrong.IsSolutionUsable()) << wrong.message;
  std::printf("held-out residual: true centre %.4f, 1.5 px off %.4f, noise floor %.4f\n", right.relative_residual,
              wrong.relative_residual, right.noise_floor);
  EXPECT_GT(wrong.relative_residual, 1.2 * right.relative_residual);
}

// Views in any order and repeated angles: the split is by distinct angle, so
// a repeat never predicts its twin.
TEST(HeldOut, SplitsDistinctAnglesInAnyOrder) {
  SliceProblem problem(32, 16);
  Geometry geometry = problem.geometry;
  std::vector<double> angles = geometry.angles_rad;
  angles.push_back(angles[3]);  // a repeat
  std::reverse(angles.begin(), angles.end());
  geometry.angles_rad = angles;
  problem.geometry = geometry;
  const Absorbance data = problem.Exact();
  HeldOutOptions options;
  options.reconstruct.stop_rule = StopRule::kIterations;
  options.reconstruct.max_iterations = 20;
  const HeldOutSummary s = HeldOutResidual(problem.grid, geometry, data, options);
  ASSERT_TRUE(s.IsSolutionUsable()) << s.message;
  EXPECT_EQ(s.fit_views + s.held_out_views, 17);
  EXPECT_EQ(s.held_out_views, 9);  // 16 distinct angles, 8 odd ones and the repeat of the odd angle 3
  Geometry one = geometry;
  one.angles_rad.assign(17, 0.0);
  EXPECT_EQ(HeldOutResidual(problem.grid, one, data, options).termination, solvers::core::Termination::kFailure);
}

}  // namespace
}  // namespace photorig::solvers::tomography
