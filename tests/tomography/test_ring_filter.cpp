#include "photorig/solvers/tomography/ring_filter.h"

#include "slice_problem.h"

#include <gtest/gtest.h>

#include <random>

namespace photorig::solvers::tomography {
namespace {

using testing_support::SliceProblem;

double SartError(const SliceProblem& problem, const Absorbance& data) {
  ReconstructOptions options;
  options.method = Method::kSart;
  options.stop_rule = StopRule::kIterations;
  options.max_iterations = 10;
  options.stagnation_tolerance = 0.0;
  Eigen::VectorXf sigma;
  EXPECT_TRUE(Reconstruct(*problem.projector, data, options, &sigma).IsSolutionUsable());
  return problem.Error(sigma);
}

// Five detector columns whose gain is 4-8 % off their flat, two of them one
// column apart: rings in the slice. The filter finds them and brings the
// error back within 5 % of the clean scan's.
TEST(RingFilter, RemovesTheStripesOfBadDetectorColumns) {
  SliceProblem problem(64, 64);
  Absorbance clean = problem.Exact();
  std::mt19937 rng(7);
  std::normal_distribution<float> gauss(0.0f, 0.005f * clean.b.maxCoeff());
  for (auto& v : clean.b) v += gauss(rng);
  Absorbance striped = clean;
  const std::vector<std::pair<int, double>> bad = {{12, 1.05}, {27, 0.93}, {31, 1.08}, {33, 0.96}, {50, 1.04}};
  for (int view = 0; view < problem.geometry.views(); ++view)
    for (const auto& [col, gain] : bad) striped.b[problem.geometry.RayIndex(view, 0, col)] -= static_cast<float>(std::log(gain));

  const double clean_error = SartError(problem, clean), striped_error = SartError(problem, striped);
  Absorbance filtered = striped;
  const RingFilterSummary s = RemoveStripes(problem.geometry, {}, &filtered);
  ASSERT_EQ(s.termination, solvers::core::Termination::kSuccess) << s.message;
  EXPECT_GE(s.stripes, 5);
  EXPECT_LE(s.stripes, 8);
  const double filtered_error = SartError(problem, filtered);
  std::printf("error: clean %.4f, striped %.4f, filtered %.4f (%d stripes, largest %.4f)\n", clean_error, striped_error,
              filtered_error, s.stripes, s.max_offset);
  EXPECT_GT(striped_error, 1.2 * clean_error);
  EXPECT_LT(filtered_error, 1.05 * clean_error);
  // On a scan without stripes it changes next to nothing.
  Absorbance clean_filtered = clean;
  EXPECT_LE(RemoveStripes(problem.geometry, {}, &clean_filtered).stripes, 2);
  EXPECT_LT(SartError(problem, clean_filtered), 1.03 * clean_error);
}

TEST(RingFilter, RefusesBadOptionsAndInput) {
  SliceProblem problem(16, 8);
  Absorbance data = problem.Exact();
  RingFilterOptions none;
  none.neighbours_px = 0;
  EXPECT_EQ(RemoveStripes(problem.geometry, none, &data).termination, solvers::core::Termination::kInvalidOptions);
  Absorbance short_data;
  short_data.b.setZero(3);
  EXPECT_EQ(RemoveStripes(problem.geometry, {}, &short_data).termination, solvers::core::Termination::kInvalidInput);
}

}  // namespace
}  // namespace photorig::solvers::tomography
