#include "photorig/sim/phantom.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

namespace photorig::sim {
namespace {

TEST(Phantom, LineIntegralOfABallIsItsChordTimesSigma) {
  Phantom ball;
  ball.half_extent_mm = 10.0;
  ball.sigma_per_mm = 0.2;
  ball.ellipsoids = {{1.0, 0.5, 0.5, 0.5, 0, 0, 0, 0, 0, 0}};  // radius 5 mm
  // A ray at distance 3 mm from the centre: chord 2 sqrt(25 - 9) = 8 mm.
  EXPECT_NEAR(ball.LineIntegral({-20, 3, 0}, {1, 0, 0}), 0.2 * 8.0, 1e-9);
  EXPECT_NEAR(ball.LineIntegral({-20, 0, 6}, {1, 0, 0}), 0.0, 1e-12);
  EXPECT_NEAR(ball.Sigma({0, 4.9, 0}), 0.2, 1e-12);
}

TEST(Phantom, SheppLoganCentralSliceHasTheTableValues) {
  const Phantom p = Phantom::SheppLogan3d(32.0, 1.0);
  // Between the ventricles: outer skull 1, brain -0.8 -> 0.2; the skull rim at
  // y = 0.9 (unit cube) has only the outer ellipsoid -> 1.
  EXPECT_NEAR(p.Sigma({0, 0, 0}), 0.2, 1e-12);
  EXPECT_NEAR(p.Sigma({0, 0.9 * 32.0, 0}), 1.0, 1e-12);
  // The ventricle at x = 0.22 takes 0.2 off: 0.
  EXPECT_NEAR(p.Sigma({0.22 * 32.0, 0, 0}), 0.0, 1e-12);
  // Rasterised and projected agree: the sum of a slice's line integrals
  // along x times the pitch is the slice's mass.
  const solvers::tomography::VolumeGrid grid{64, 64, 1, 1.0};
  const std::vector<float> slice = p.Rasterise(grid, 4);
  double mass = 0.0;
  for (float s : slice) mass += s;  // voxel area 1 mm^2
  const Phantom p2 = Phantom::SheppLogan2d(32.0, 1.0);
  const std::vector<float> slice2 = p2.Rasterise(grid, 4);
  double mass2 = 0.0, projected = 0.0;
  for (float s : slice2) mass2 += s;
  for (int i = 0; i < 640; ++i) projected += p2.LineIntegral({-100, (i + 0.5) * 0.1 - 32.0, 0}, {1, 0, 0}) * 0.1;
  EXPECT_NEAR(projected, mass2, 0.01 * mass2);
  EXPECT_GT(mass, 0.0);
}

// The sampler computes each ellipsoid's frame once; its values are the
// phantom's own, bit for bit, and Rasterise (which uses it) gives what
// averaging Phantom::Sigma gives.
TEST(Phantom, SamplerGivesThePhantomsValuesExactly) {
  const Phantom p = Phantom::SheppLogan3d(12.0, 0.2);
  const PhantomSampler sampler(p);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-13.0, 13.0);
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Vector3d point(u(rng), u(rng), u(rng));
    EXPECT_EQ(sampler.Sigma(point), p.Sigma(point));
    const Eigen::Vector3d direction = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    EXPECT_EQ(sampler.LineIntegral(point, direction), p.LineIntegral(point, direction));
  }
  const solvers::tomography::VolumeGrid grid{6, 5, 4, 4.0};
  const std::vector<float> raster = p.Rasterise(grid, 2);
  for (int k = 0; k < grid.nz; ++k)
    for (int j = 0; j < grid.ny; ++j)
      for (int i = 0; i < grid.nx; ++i) {
        double sum = 0.0;
        for (int c = 0; c < 2; ++c)
          for (int b = 0; b < 2; ++b)
            for (int a = 0; a < 2; ++a)
              sum += p.Sigma(grid.VoxelCentre(i, j, k) + grid.voxel_mm * Eigen::Vector3d(0.5 * a - 0.25, 0.5 * b - 0.25,
                                                                                         0.5 * c - 0.25));
        EXPECT_EQ(raster[static_cast<std::size_t>(grid.Index(i, j, k))], static_cast<float>(sum / 8));
      }
}

TEST(Phantom, ScanFramesFollowTheBeerLambertLaw) {
  Phantom ball;
  ball.half_extent_mm = 4.0;
  ball.sigma_per_mm = 0.1;
  ball.ellipsoids = {{1.0, 1.0, 1.0, 1.0, 0, 0, 0, 0, 0, 0}};
  solvers::tomography::Geometry g;
  g.detector_cols = 3;
  g.detector_rows = 3;
  g.pixel_mm = 1.0;
  g.angles_rad = {0.0, 1.0};
  TomographyScanOptions options;
  options.sensor.shot_noise = false;
  options.sensor.read_noise_e = 0.0;
  options.supersample = 1;  // the centre ray alone: tau = 0.1 * 8
  const TomographyScan scan = ScanPhantom(ball, g, options);
  ASSERT_EQ(scan.projections.size(), 2u);
  const double black = options.sensor.black_level_dn;
  const double flat = scan.flats[0][4] - black, centre = scan.projections[1][4] - black;
  EXPECT_NEAR(centre / flat, std::exp(-0.1 * 8.0), 2.0 / flat);  // whole-DN rounding
}

}  // namespace
}  // namespace photorig::sim
