#include "photorig/solvers/tomography/absorbance.h"

#include "photorig/sim/phantom.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace photorig::solvers::tomography {
namespace {

Geometry OneView(int cols, int rows) {
  Geometry g;
  g.detector_cols = cols;
  g.detector_rows = rows;
  g.angles_rad = {0.0};
  return g;
}

TEST(Absorbance, IsMinusTheLogOfTheDarkCorrectedRatio) {
  const Geometry g = OneView(3, 1);
  // Dark 100, flat 1100: L - D of 500, 1000, 100.
  const std::vector<std::vector<std::uint16_t>> frames{{600, 1100, 200}}, flats{{1100, 1100, 1100}},
      darks{{100, 100, 100}};
  Absorbance a;
  const AbsorbanceSummary s = ComputeAbsorbance(g, frames, flats, darks, {}, &a);
  ASSERT_EQ(s.termination, solvers::core::Termination::kSuccess) << s.message;
  EXPECT_NEAR(a.b[0], std::log(2.0), 1e-6);
  EXPECT_NEAR(a.b[1], 0.0, 1e-6);
  EXPECT_NEAR(a.b[2], std::log(10.0), 1e-6);
  EXPECT_FALSE(s.noise_estimated) << "one flat and one dark carry no variance";
  EXPECT_EQ(a.variance.size(), 0);
}

TEST(Absorbance, FlagsNonPositiveSaturatedAndUnlitPixelsInsteadOfClipping) {
  const Geometry g = OneView(5, 1);
  // Pixel 0 fine; 1 below the dark; 2 saturated in the frame; 3 saturated in a flat; 4 unlit flat.
  const std::vector<std::vector<std::uint16_t>> frames{{600, 90, 4095, 600, 101}},
      flats{{1100, 1100, 1100, 4095, 102}}, darks{{100, 100, 100, 100, 100}};
  Absorbance a;
  const AbsorbanceSummary s = ComputeAbsorbance(g, frames, flats, darks, {}, &a);
  ASSERT_TRUE(s.IsSolutionUsable());
  EXPECT_EQ(a.valid, (std::vector<std::uint8_t>{1, 0, 0, 0, 0}));
  EXPECT_EQ(s.flagged_non_positive, 1);
  EXPECT_EQ(s.flagged_saturated, 2);
  EXPECT_EQ(s.flagged_no_flat, 1);
  EXPECT_NE(s.message.find("4 of 5"), std::string::npos) << s.message;
  // Every pixel flagged: nothing to reconstruct from.
  const std::vector<std::vector<std::uint16_t>> dark_frames{{50, 50, 50, 50, 50}};
  EXPECT_EQ(ComputeAbsorbance(g, dark_frames, flats, darks, {}, &a).termination, solvers::core::Termination::kFailure);
}

TEST(Absorbance, NoiseEstimateFromFlatsAndDarksMatchesTheScatterOfB) {
  // A uniform slab of tau = 0.7 seen in many views: the spread of b across
  // rays is the noise the estimate predicts (within 10 %).
  Geometry g = OneView(64, 8);
  g.angles_rad = EvenAngles(40, 180.0);
  // A cylinder of radius 1 mm about the axis; every ray passes within 0.03 mm of
  // the axis, where the chord is 2 mm: tau = 0.35 * 2 = 0.7.
  sim::Phantom slab;
  slab.half_extent_mm = 1.0;
  slab.sigma_per_mm = 1.0;
  slab.ellipsoids = {{0.35, 1.0, 1.0, std::numeric_limits<double>::infinity(), 0, 0, 0, 0, 0, 0}};
  g.pixel_mm = 1e-3;
  sim::TomographyScanOptions options;
  options.flats = 16;
  options.darks = 16;
  const sim::TomographyScan scan = sim::ScanPhantom(slab, g, options);
  Absorbance a;
  const AbsorbanceSummary s = ComputeAbsorbance(g, scan.projections, scan.flats, scan.darks, {}, &a);
  ASSERT_TRUE(s.IsSolutionUsable()) << s.message;
  ASSERT_TRUE(s.noise_estimated);
  EXPECT_NEAR(s.read_variance_dn2, std::pow(options.sensor.read_noise_e / options.sensor.e_per_dn, 2), 0.3);
  EXPECT_NEAR(s.gain_dn_per_dn, 1.0 / options.sensor.e_per_dn, 0.02);
  const double mean = a.b.mean();
  EXPECT_NEAR(mean, 0.7, 0.01);
  const double spread = std::sqrt((a.b.array() - mean).square().mean());
  EXPECT_NEAR(s.mean_b_sigma, spread, 0.1 * spread);
}

}  // namespace
}  // namespace photorig::solvers::tomography
