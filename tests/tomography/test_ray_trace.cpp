#include "photorig/solvers/tomography/ray_trace.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

namespace photorig::solvers::tomography {
namespace {

double Sum(const std::vector<RayWeight>& weights) {
  double sum = 0.0;
  for (const RayWeight& w : weights) sum += w.weight_mm;
  return sum;
}

VolumeGrid Cube(int n, double voxel_mm) { return VolumeGrid{n, n, n, voxel_mm}; }

TEST(RayTrace, SiddonLengthsSumToTheChordsOfACube) {
  // A cube of side 8 mm in 16^3 voxels; chords known in closed form.
  const VolumeGrid grid = Cube(16, 0.5);
  const double h = 4.0;
  std::vector<RayWeight> w;
  struct Case {
    Eigen::Vector3d origin, direction;
    double chord;
  };
  const Case cases[] = {
      {{-10, 0.3, -1.1}, Eigen::Vector3d(1, 0, 0), 2 * h},                                 // along x
      {{-10, -10, 0.2}, Eigen::Vector3d(1, 1, 0).normalized(), 2 * h * std::sqrt(2.0)},   // face diagonal
      {{-10, -10, -10}, Eigen::Vector3d(1, 1, 1).normalized(), 2 * h * std::sqrt(3.0)},   // space diagonal
      {{0, 1.5, 0.7}, Eigen::Vector3d(1, 1, 0).normalized(), std::sqrt(2.0) * (2 * h - 1.5)},  // y = x + 1.5
      {{3.0, 3.0, 9.0}, Eigen::Vector3d(0, 0, -1), 2 * h},                                 // along -z
  };
  for (const Case& c : cases) {
    TraceRay(grid, c.origin, c.direction, Interpolation::kSiddon, &w);
    EXPECT_NEAR(Sum(w), c.chord, 1e-5) << c.direction.transpose();
  }
  TraceRay(grid, {-10, 5.0, 0}, Eigen::Vector3d(1, 0, 0), Interpolation::kSiddon, &w);
  EXPECT_TRUE(w.empty()) << "a ray beside the cube crosses nothing";
}

TEST(RayTrace, SiddonLengthsPerVoxelMatchAHandComputedRay) {
  // 2 x 2 voxels of 1 mm (x, y in [-1, 1]), one slice. The ray y = -0.75 + (x + 1) / 2
  // crosses voxel (0,0) for x in [-1, 0], (1,0) for x in [0, 0.5], (1,1) for x in [0.5, 1].
  const VolumeGrid grid{2, 2, 1, 1.0};
  std::vector<RayWeight> w;
  TraceRay(grid, {-1.0, -0.75, 0.0}, Eigen::Vector3d(2, 1, 0).normalized(), Interpolation::kSiddon, &w);
  std::map<std::int64_t, double> by_voxel;
  for (const RayWeight& r : w) by_voxel[r.voxel] += r.weight_mm;
  const double s = std::sqrt(1.25);  // path per mm of x
  ASSERT_EQ(by_voxel.size(), 3u);
  EXPECT_NEAR(by_voxel[grid.Index(0, 0, 0)], 1.0 * s, 1e-6);
  EXPECT_NEAR(by_voxel[grid.Index(1, 0, 0)], 0.5 * s, 1e-6);
  EXPECT_NEAR(by_voxel[grid.Index(1, 1, 0)], 0.5 * s, 1e-6);
}

TEST(RayTrace, JosephWeightsSumToTheChordAwayFromTheEdges) {
  const VolumeGrid grid = Cube(32, 0.25);
  std::vector<RayWeight> w;
  // Dominant axis x: every layer contributes voxel / |d_x| of path.
  const Eigen::Vector3d d = Eigen::Vector3d(1, 0.3, -0.2).normalized();
  TraceRay(grid, {0.1, -0.2, 0.05}, d, Interpolation::kJoseph, &w);
  EXPECT_NEAR(Sum(w), 8.0 / d.x(), 1e-4);
  // Interpolated: a ray between voxel centres spreads over two columns.
  TraceRay(grid, {-10, 0.0, 0.125}, Eigen::Vector3d(1, 0, 0), Interpolation::kJoseph, &w);
  EXPECT_EQ(w.size(), 64u);
  EXPECT_NEAR(Sum(w), 8.0, 1e-5);
  EXPECT_NEAR(w.front().weight_mm, 0.125, 1e-6);
}

TEST(RayTrace, NamesParse) {
  EXPECT_EQ(ParseInterpolation("siddon"), Interpolation::kSiddon);
  EXPECT_EQ(ParseInterpolation("joseph"), Interpolation::kJoseph);
  EXPECT_FALSE(ParseInterpolation("nearest"));
  EXPECT_STREQ(InterpolationName(Interpolation::kJoseph), "joseph");
}

}  // namespace
}  // namespace photorig::solvers::tomography
