#include "photorig/solvers/tomography/center_of_rotation.h"

#include "slice_problem.h"

#include <gtest/gtest.h>

#include <random>

namespace photorig::solvers::tomography {
namespace {

using testing_support::SliceProblem;

TEST(CentreOfRotation, RecoversAKnownOffsetFromOpposingViews) {
  for (double offset_mm : {0.0, 0.37, -1.1}) {
    SliceProblem problem(64, 60, 360.0, offset_mm);
    Absorbance data = problem.Exact();
    std::mt19937 rng(11);
    std::normal_distribution<float> gauss(0.0f, 0.01f * data.b.maxCoeff());
    for (auto& v : data.b) v += gauss(rng);
    Geometry assumed = problem.geometry;
    assumed.cor_offset_mm = 0.0;  // what a rig file that knows nothing would say
    const CorEstimateSummary s = EstimateCorOffset(assumed, data);
    ASSERT_EQ(s.termination, solvers::core::Termination::kSuccess) << s.message;
    EXPECT_EQ(s.pairs, 30);
    // A tenth of a pixel (0.05 mm).
    EXPECT_NEAR(s.offset_mm, offset_mm, 0.05);
  }
}

TEST(CentreOfRotation, SaysWhyItCannotEstimate) {
  SliceProblem half_scan(32, 32, 180.0);  // 0..180 without its end view: no opposing pair
  const CorEstimateSummary s = EstimateCorOffset(half_scan.geometry, half_scan.Exact());
  EXPECT_EQ(s.termination, solvers::core::Termination::kFailure);
  EXPECT_NE(s.message.find("180 degrees apart"), std::string::npos) << s.message;
  Geometry with_end = half_scan.geometry;
  with_end.angles_rad = EvenAngles(32, 180.0, true);
  SliceProblem problem(32, 32);
  problem.geometry = with_end;
  EXPECT_EQ(EstimateCorOffset(with_end, problem.Exact()).pairs, 1);
  Geometry cone = half_scan.geometry;
  cone.beam = Beam::kCone;
  EXPECT_EQ(EstimateCorOffset(cone, half_scan.Exact()).termination, solvers::core::Termination::kFailure);
}

}  // namespace
}  // namespace photorig::solvers::tomography
