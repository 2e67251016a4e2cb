#include "photorig/solvers/tomography/center_of_rotation.h"

#include "photorig/sim/phantom.h"
#include "slice_problem.h"

#include <gtest/gtest.h>

#include <cmath>
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

// A 64-pixel slice scan of a Shepp-Logan head small enough (20 mm across on a
// 32 mm detector) to stay on the detector with the axis 8 px off its centre,
// 1 % noise, and its reconstruction error at a given centre.
struct OffsetScan {
  VolumeGrid grid{64, 64, 1, 0.5};
  Geometry geometry;
  sim::Phantom phantom = sim::Phantom::SheppLogan2d(11.0, 0.1);
  Absorbance data;
  Eigen::VectorXf truth;

  OffsetScan(double offset_px, std::vector<double> angles_rad, Beam beam = Beam::kParallel, unsigned seed = 3) {
    geometry.beam = beam;
    geometry.detector_cols = 64;
    geometry.detector_rows = beam == Beam::kCone ? 2 : 1;
    geometry.pixel_mm = 0.5;
    geometry.source_to_axis_mm = 150.0;
    geometry.axis_to_detector_mm = 50.0;
    geometry.angles_rad = std::move(angles_rad);
    geometry.cor_offset_mm = offset_px * geometry.pixel_mm;
    const std::vector<float> b = sim::ProjectPhantom(phantom, geometry);
    data.b = Eigen::Map<const Eigen::VectorXf>(b.data(), static_cast<Eigen::Index>(b.size()));
    std::mt19937 rng(seed);
    std::normal_distribution<float> gauss(0.0f, 0.01f * data.b.maxCoeff());
    for (auto& v : data.b) v += gauss(rng);
    const std::vector<float> raster = phantom.Rasterise(grid, 4);
    truth = Eigen::Map<const Eigen::VectorXf>(raster.data(), static_cast<Eigen::Index>(raster.size()));
  }

  // Relative L2 error of SART (10 passes) with the axis at offset_mm.
  double ErrorAt(double offset_mm) const {
    Geometry assumed = geometry;
    assumed.cor_offset_mm = offset_mm;
    std::unique_ptr<Projector> w;
    EXPECT_TRUE(MakeProjector(grid, assumed, {}, &w).IsSolutionUsable());
    ReconstructOptions options = CorSearchOptions::CandidateReconstruction().reconstruct;
    Eigen::VectorXf sigma;
    EXPECT_TRUE(Reconstruct(*w, data, options, &sigma).IsSolutionUsable());
    return (sigma - truth).norm() / truth.norm();
  }
};

// The acceptance: offsets across -8 .. +8 px, the centre within 0.25
// px, and the reconstruction at the estimate within 5 % of the error at the
// true centre.
TEST(CentreOfRotation, OpposingViewsFindOffsetsAcrossEightPixelsWithTheirUncertainty) {
  for (double offset_px : {-8.0, -5.5, -2.25, -0.5, 0.0, 1.3, 4.75, 8.0}) {
    SCOPED_TRACE(offset_px);
    const OffsetScan scan(offset_px, EvenAngles(90, 180.0, true));
    Geometry assumed = scan.geometry;
    assumed.cor_offset_mm = 0.0;
    const CorEstimateSummary s = EstimateCorOffset(assumed, scan.data);
    ASSERT_EQ(s.termination, solvers::core::Termination::kSuccess) << s.message;
    const double error_px = s.offset_mm / assumed.pixel_mm - offset_px;
    EXPECT_LT(std::abs(error_px), 0.25);
    // The uncertainty is finite, and the error within three of it (or a twentieth of a pixel).
    EXPECT_GT(s.offset_sigma_mm, 0.0);
    EXPECT_LT(std::abs(error_px), std::max(3.0 * s.offset_sigma_mm / assumed.pixel_mm, 0.05));
    EXPECT_LT(scan.ErrorAt(s.offset_mm), 1.05 * scan.ErrorAt(scan.geometry.cor_offset_mm));
    std::printf("offset %+.2f px: found %+.3f px (error %+.3f, sigma %.3f px)\n", offset_px,
                s.offset_mm / assumed.pixel_mm, error_px, s.offset_sigma_mm / assumed.pixel_mm);
  }
}

// Without opposing views (0..180 without its end view, a cone beam) the
// held-out residual's minimum finds the centre.
TEST(CentreOfRotation, TheHeldOutSearchFindsTheCentreWithoutOpposingViews) {
  struct Case {
    double offset_px;
    Beam beam;
  };
  for (const Case& c : {Case{-7.5, Beam::kParallel}, Case{2.3, Beam::kParallel}, Case{-3.6, Beam::kCone}}) {
    SCOPED_TRACE(c.offset_px);
    // The cone beam over a full turn (its opposite views are no mirror images), with fewer views to keep it quick.
    const OffsetScan scan(c.offset_px, c.beam == Beam::kCone ? EvenAngles(40, 360.0) : EvenAngles(64, 180.0), c.beam);
    Geometry assumed = scan.geometry;
    assumed.cor_offset_mm = 0.0;
    ASSERT_EQ(EstimateCorOffset(assumed, scan.data).termination, solvers::core::Termination::kFailure);
    const CorEstimateSummary s = SearchCorOffset(assumed, scan.data);
    ASSERT_EQ(s.termination, solvers::core::Termination::kSuccess) << s.message;
    EXPECT_EQ(s.method, CorMethod::kHeldOutSearch);
    const double error_px = s.offset_mm / assumed.pixel_mm - c.offset_px;
    EXPECT_LT(std::abs(error_px), 0.25);
    EXPECT_GT(s.offset_sigma_mm, 0.0);
    EXPECT_LT(s.offset_sigma_mm / assumed.pixel_mm, 0.5);
    std::printf("search, offset %+.2f px: found %+.3f px (sigma %.3f px, %d candidates, held-out residual %.4f, %.0f ms)\n",
                c.offset_px, s.offset_mm / assumed.pixel_mm, s.offset_sigma_mm / assumed.pixel_mm, s.candidates,
                s.held_out_residual, s.total_ms);
  }
}

// A detector turned in its plane: the axis' column drifts along the rows.
// Each row is scanned with its own offset, 0.05 px more a row (2.9 degrees).
TEST(CentreOfRotation, OpposingViewsMeasureTheDetectorTilt) {
  constexpr int kRows = 16;
  constexpr double kSlopePxPerRow = 0.05;
  const OffsetScan first(0.0, EvenAngles(60, 360.0));
  Geometry tilted = first.geometry;
  tilted.detector_rows = kRows;
  tilted.cor_offset_mm = 0.0;
  Absorbance data;
  data.b.resize(tilted.rays());
  for (int row = 0; row < kRows; ++row) {
    const OffsetScan scan(2.0 + kSlopePxPerRow * (row - 0.5 * (kRows - 1)), EvenAngles(60, 360.0), Beam::kParallel,
                          static_cast<unsigned>(row + 1));
    for (int view = 0; view < tilted.views(); ++view)
      for (int col = 0; col < tilted.detector_cols; ++col)
        data.b[tilted.RayIndex(view, row, col)] = scan.data.b[scan.geometry.RayIndex(view, 0, col)];
  }
  const CorEstimateSummary s = EstimateCorOffset(tilted, data);
  ASSERT_EQ(s.termination, solvers::core::Termination::kSuccess) << s.message;
  EXPECT_NEAR(s.offset_mm / tilted.pixel_mm, 2.0, 0.1);
  const double expected_deg = std::atan(kSlopePxPerRow) * 180.0 / M_PI;
  std::printf("tilt %.3f deg (sigma %.3f), simulated %.3f; %s\n", s.tilt_deg, s.tilt_sigma_deg, expected_deg, s.message.c_str());
  EXPECT_NEAR(s.tilt_deg, expected_deg, std::max(3.0 * s.tilt_sigma_deg, 0.3));
  EXPECT_NE(s.message.find("tilted"), std::string::npos) << s.message;
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
  // A centre beyond the searched range is not guessed at.
  CorSearchOptions narrow;
  narrow.max_offset_mm = 1.0;
  const OffsetScan far(6.0, EvenAngles(32, 180.0));
  Geometry assumed = far.geometry;
  assumed.cor_offset_mm = 0.0;
  const CorEstimateSummary edge = SearchCorOffset(assumed, far.data, narrow);
  EXPECT_EQ(edge.termination, solvers::core::Termination::kFailure);
  EXPECT_NE(edge.message.find("edge of the search"), std::string::npos) << edge.message;
}

}  // namespace
}  // namespace photorig::solvers::tomography
