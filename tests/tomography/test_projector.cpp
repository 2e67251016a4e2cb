#include "photorig/solvers/tomography/projector.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <ostream>
#include <utility>
#include <vector>
#include <random>
#include <string>

namespace photorig::solvers::tomography {
namespace {

Geometry Scan(Beam beam, int views, int cols, int rows, double pixel_mm) {
  Geometry g;
  g.beam = beam;
  g.detector_cols = cols;
  g.detector_rows = rows;
  g.pixel_mm = pixel_mm;
  g.angles_rad = EvenAngles(views, 360.0);
  g.cor_offset_mm = 0.13;
  g.source_to_axis_mm = 40.0;
  g.axis_to_detector_mm = 20.0;
  return g;
}

Eigen::VectorXf Random(std::int64_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  Eigen::VectorXf v(n);
  for (auto& x : v) x = u(rng);
  return v;
}

struct AdjointCase {
  Beam beam;
  Interpolation interpolation;
  Storage storage;

  std::string Name() const {  // ParallelSiddonSparse, ConeJosephMatrixFree, ...
    return std::string(beam == Beam::kParallel ? "Parallel" : "Cone") +
           (interpolation == Interpolation::kSiddon ? "Siddon" : "Joseph") +
           (storage == Storage::kSparse ? "Sparse" : "MatrixFree");
  }
};

// CTest shows the case by name, not as a dump of its bytes.
void PrintTo(const AdjointCase& c, std::ostream* out) { *out << c.Name(); }

class Adjoint : public testing::TestWithParam<AdjointCase> {};

TEST_P(Adjoint, BackProjectionIsTheTransposeOfProjection) {
  const AdjointCase c = GetParam();
  const VolumeGrid grid{12, 10, 8, 1.0};
  const Geometry geometry = Scan(c.beam, 9, 20, 14, 1.1);
  ProjectorOptions options;
  options.interpolation = c.interpolation;
  options.storage = c.storage;
  std::unique_ptr<Projector> w;
  ASSERT_TRUE(MakeProjector(grid, geometry, options, &w).IsSolutionUsable());
  EXPECT_EQ(w->is_sparse(), c.storage == Storage::kSparse);
  const Eigen::VectorXf x = Random(w->voxels(), 1), y = Random(w->rays(), 2);
  Eigen::VectorXf wx, wty;
  w->Forward(x, &wx);
  w->Back(y, &wty);
  const double lhs = wx.cast<double>().dot(y.cast<double>()), rhs = x.cast<double>().dot(wty.cast<double>());
  EXPECT_NEAR(lhs, rhs, 1e-5 * (std::abs(lhs) + std::abs(rhs)));
  EXPECT_GT(wx.norm(), 0.0f) << "the rays must cross the grid";
}

INSTANTIATE_TEST_SUITE_P(
    AllProjectors, Adjoint,
    testing::Values(AdjointCase{Beam::kParallel, Interpolation::kSiddon, Storage::kSparse},
                    AdjointCase{Beam::kParallel, Interpolation::kSiddon, Storage::kMatrixFree},
                    AdjointCase{Beam::kParallel, Interpolation::kJoseph, Storage::kSparse},
                    AdjointCase{Beam::kCone, Interpolation::kSiddon, Storage::kMatrixFree},
                    AdjointCase{Beam::kCone, Interpolation::kJoseph, Storage::kSparse},
                    AdjointCase{Beam::kCone, Interpolation::kJoseph, Storage::kMatrixFree}),
    [](const testing::TestParamInfo<AdjointCase>& info) { return info.param.Name(); });

// A slab decomposition's W (solvers/tomography_mpi) is the whole grid's W
// cut by columns into runs of z-slices: each slab's rows are exactly the
// whole rows' entries on its voxels, so that forward projections of the
// slabs add up to the whole grid's and back projections are its pieces.
class Slabs : public testing::TestWithParam<AdjointCase> {};

TEST_P(Slabs, ProjectionsOfTheSlabsAddUpToTheWholeGrids) {
  const AdjointCase c = GetParam();
  const VolumeGrid grid{12, 10, 8, 1.0};
  // Nine rows of the voxel pitch: parallel rows at whole millimetres, and the
  // cone's central row at z = 0, lie exactly on the faces between slices,
  // where the slabs below start (z = -1: slice 3, z = 0: slice 4).
  const Geometry geometry = Scan(c.beam, 9, 20, 9, 1.0);
  ProjectorOptions options;
  options.interpolation = c.interpolation;
  options.storage = c.storage;
  std::unique_ptr<Projector> whole;
  ASSERT_TRUE(MakeProjector(grid, geometry, options, &whole).IsSolutionUsable());
  const Eigen::VectorXf x = Random(grid.voxels(), 5), y = Random(geometry.rays(), 6);
  Eigen::VectorXf whole_forward, whole_back;
  whole->Forward(x, &whole_forward);
  whole->Back(y, &whole_back);
  ASSERT_GT(whole_forward.norm(), 0.0f);

  const int per_slice = grid.nx * grid.ny;
  Eigen::VectorXf sum = Eigen::VectorXf::Zero(geometry.rays());
  std::vector<std::vector<RayWeight>> rows(static_cast<std::size_t>(geometry.rays()));
  for (const auto& [first, count] : {std::pair{0, 3}, std::pair{3, 1}, std::pair{4, 4}}) {
    ProjectorOptions slab_options = options;
    slab_options.first_slice = first;
    slab_options.slices = count;
    std::unique_ptr<Projector> slab;
    ASSERT_TRUE(MakeProjector(grid, geometry, slab_options, &slab).IsSolutionUsable());
    ASSERT_EQ(slab->voxels(), std::int64_t{per_slice} * count);
    Eigen::VectorXf forward, back;
    slab->Forward(x.segment(std::int64_t{first} * per_slice, slab->voxels()), &forward);
    sum += forward;
    slab->Back(y, &back);
    const Eigen::VectorXf piece = whole_back.segment(std::int64_t{first} * per_slice, slab->voxels());
    EXPECT_LT((back - piece).norm(), 1e-6 * piece.norm()) << "slices " << first << " + " << count;
    std::vector<RayWeight> weights;
    for (std::int64_t ray = 0; ray < geometry.rays(); ++ray) {
      slab->Row(ray, &weights);
      for (const RayWeight& w : weights)
        rows[static_cast<std::size_t>(ray)].push_back({w.voxel + first * per_slice, w.weight_mm});
    }
  }
  EXPECT_LT((sum - whole_forward).norm(), 1e-6 * whole_forward.norm());
  // Entry by entry: the same voxels with the very same weights.
  std::vector<RayWeight> weights;
  for (std::int64_t ray = 0; ray < geometry.rays(); ++ray) {
    whole->Row(ray, &weights);
    auto& pieces = rows[static_cast<std::size_t>(ray)];
    auto by_voxel = [](const RayWeight& l, const RayWeight& r) { return l.voxel < r.voxel; };
    std::sort(weights.begin(), weights.end(), by_voxel);
    std::sort(pieces.begin(), pieces.end(), by_voxel);
    ASSERT_EQ(pieces.size(), weights.size()) << "ray " << ray;
    for (std::size_t i = 0; i < weights.size(); ++i) {
      EXPECT_EQ(pieces[i].voxel, weights[i].voxel) << "ray " << ray;
      EXPECT_EQ(pieces[i].weight_mm, weights[i].weight_mm) << "ray " << ray;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    AllProjectors, Slabs,
    testing::Values(AdjointCase{Beam::kParallel, Interpolation::kSiddon, Storage::kSparse},
                    AdjointCase{Beam::kParallel, Interpolation::kJoseph, Storage::kMatrixFree},
                    AdjointCase{Beam::kCone, Interpolation::kSiddon, Storage::kMatrixFree},
                    AdjointCase{Beam::kCone, Interpolation::kJoseph, Storage::kSparse}),
    [](const testing::TestParamInfo<AdjointCase>& info) { return info.param.Name(); });

TEST(Projector, SlicesPastTheGridAreInvalidOptions) {
  ProjectorOptions options;
  options.first_slice = 6;
  options.slices = 3;
  std::unique_ptr<Projector> w;
  const ProjectorSummary s = MakeProjector({8, 8, 8, 0.5}, Scan(Beam::kParallel, 4, 8, 8, 0.5), options, &w);
  EXPECT_EQ(s.termination, solvers::core::Termination::kInvalidOptions);
  EXPECT_NE(s.message.find("past the grid"), std::string::npos) << s.message;
  options.slices = 2;
  ASSERT_TRUE(MakeProjector({8, 8, 8, 0.5}, Scan(Beam::kParallel, 4, 8, 8, 0.5), options, &w).IsSolutionUsable());
  EXPECT_EQ(w->voxels(), 8 * 8 * 2);
}

TEST(Projector, SparseAndMatrixFreeGiveTheSameProducts) {
  const VolumeGrid grid{16, 16, 4, 0.5};
  const Geometry geometry = Scan(Beam::kCone, 7, 24, 6, 0.5);
  ProjectorOptions sparse_options, free_options;
  sparse_options.storage = Storage::kSparse;
  free_options.storage = Storage::kMatrixFree;
  std::unique_ptr<Projector> sparse, free;
  ASSERT_TRUE(MakeProjector(grid, geometry, sparse_options, &sparse).IsSolutionUsable());
  ASSERT_TRUE(MakeProjector(grid, geometry, free_options, &free).IsSolutionUsable());
  const Eigen::VectorXf x = Random(grid.voxels(), 3), y = Random(geometry.rays(), 4);
  Eigen::VectorXf a, b;
  sparse->Forward(x, &a);
  free->Forward(x, &b);
  EXPECT_LT((a - b).norm(), 1e-5 * a.norm());
  sparse->Back(y, &a);
  free->Back(y, &b);
  EXPECT_LT((a - b).norm(), 1e-5 * a.norm());
}

TEST(Projector, ColumnSumsOfAParallelSliceScanAreTheVoxelAreaOverThePitch) {
  // Each view's rays, spaced by the pitch p, cover a voxel of side v with
  // lengths summing to v^2 / p on average.
  const VolumeGrid grid{32, 32, 1, 0.5};
  Geometry geometry = Scan(Beam::kParallel, 30, 48, 1, 0.5);
  geometry.cor_offset_mm = 0.0;
  geometry.angles_rad = EvenAngles(30, 180.0);
  std::unique_ptr<Projector> w;
  ASSERT_TRUE(MakeProjector(grid, geometry, {}, &w).IsSolutionUsable());
  Eigen::VectorXf sums;
  w->Back(Eigen::VectorXf::Ones(geometry.rays()), &sums);
  const double expected = 30 * 0.5 * 0.5 / 0.5;
  EXPECT_NEAR(sums.mean(), expected, 0.01 * expected);
  EXPECT_NEAR(sums.minCoeff(), expected, 0.1 * expected);
  EXPECT_NEAR(sums.maxCoeff(), expected, 0.1 * expected);
}

TEST(Projector, SparseStorageOverTheBudgetFails) {
  ProjectorOptions options;
  options.storage = Storage::kSparse;
  options.memory_budget_bytes = 1024;
  std::unique_ptr<Projector> w;
  const ProjectorSummary s = MakeProjector({16, 16, 16, 0.5}, Scan(Beam::kParallel, 8, 16, 16, 0.5), options, &w);
  EXPECT_EQ(s.termination, solvers::core::Termination::kFailure);
  EXPECT_NE(s.message.find("memory_budget_bytes"), std::string::npos);
  EXPECT_GT(s.estimated_sparse_bytes, 1024u);
  EXPECT_EQ(w, nullptr);
  // kAuto falls back to matrix-free under the same budget.
  options.storage = Storage::kAuto;
  ASSERT_TRUE(MakeProjector({16, 16, 16, 0.5}, Scan(Beam::kParallel, 8, 16, 16, 0.5), options, &w).IsSolutionUsable());
  EXPECT_FALSE(w->is_sparse());
}

TEST(Projector, BadGeometryIsInvalidInput) {
  Geometry g = Scan(Beam::kParallel, 4, 8, 8, 0.5);
  g.angles_rad.clear();
  std::unique_ptr<Projector> w;
  EXPECT_EQ(MakeProjector({8, 8, 8, 0.5}, g, {}, &w).termination, solvers::core::Termination::kInvalidInput);
  EXPECT_EQ(MakeProjector({0, 8, 8, 0.5}, Scan(Beam::kParallel, 4, 8, 8, 0.5), {}, &w).termination,
            solvers::core::Termination::kInvalidInput);
}

}  // namespace
}  // namespace photorig::solvers::tomography
