// volume.vdb, as `photorig solve tomography` writes it beside volume.nrrd,
// read back with OpenVDB: the same voxels, the same voxel size and position.

#include "../daemon/test_support.h"
#include "photorig/daemon/pipelines/tomography_pipeline.h"
#include "photorig/daemon/io/internal/vdb_volume.h"
#include "photorig/solvers/tomography/nrrd.h"

#include <gtest/gtest.h>
#include <openvdb/openvdb.h>

#include <filesystem>
#include <random>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
using photorig::testing::TempDir;

TEST(VdbVolume, TheResultsVdbHoldsTheNrrdsVoxelsAndVoxelSize) {
  TomographyResult result;
  result.grid = {12, 10, 6, 0.25};
  result.sigma.resize(result.grid.voxels());
  // A ball of sigma up to 0.3/mm in empty space, with a speck of noise
  // below the tolerance that must stay inactive.
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> speck(0.0f, 1e-5f);
  for (int k = 0; k < result.grid.nz; ++k)
    for (int j = 0; j < result.grid.ny; ++j)
      for (int i = 0; i < result.grid.nx; ++i) {
        const double r = result.grid.VoxelCentre(i, j, k).norm();
        result.sigma[result.grid.Index(i, j, k)] = r < 1.2 ? static_cast<float>(0.3 * (1.2 - r) + 0.01) : speck(rng);
      }
  TempDir dir;
  WriteTomographyResults(TomographyInput{}, result, dir.path().string());

  solvers::tomography::VolumeGrid grid;
  Eigen::VectorXf nrrd;
  ASSERT_TRUE(solvers::tomography::ReadNrrd((dir.path() / "volume.nrrd").string(), &grid, &nrrd).IsSolutionUsable());
  openvdb::initialize();
  openvdb::io::File file((dir.path() / "volume.vdb").string());
  ASSERT_NO_THROW(file.open());
  const openvdb::FloatGrid::Ptr vdb = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid("sigma"));
  file.close();
  ASSERT_TRUE(vdb);
  EXPECT_EQ(vdb->background(), 0.0f);
  const openvdb::Vec3d size = vdb->voxelSize();
  EXPECT_DOUBLE_EQ(size.x(), grid.voxel_mm);
  EXPECT_DOUBLE_EQ(size.y(), grid.voxel_mm);
  EXPECT_DOUBLE_EQ(size.z(), grid.voxel_mm);
  // Index (i, j, k) lies where the NRRD's voxel (i, j, k) does.
  for (const auto& [i, j, k] : {std::array{0, 0, 0}, std::array{11, 9, 5}, std::array{3, 7, 2}}) {
    const openvdb::Vec3d world = vdb->indexToWorld(openvdb::Coord(i, j, k));
    const Eigen::Vector3d centre = grid.VoxelCentre(i, j, k);
    EXPECT_NEAR(world.x(), centre.x(), 1e-12);
    EXPECT_NEAR(world.y(), centre.y(), 1e-12);
    EXPECT_NEAR(world.z(), centre.z(), 1e-12);
  }
  const float floor = 1e-3f * nrrd.maxCoeff();
  const openvdb::FloatGrid::ConstAccessor voxels = vdb->getConstAccessor();
  std::int64_t active = 0;
  for (int k = 0; k < grid.nz; ++k)
    for (int j = 0; j < grid.ny; ++j)
      for (int i = 0; i < grid.nx; ++i) {
        const float expected = nrrd[grid.Index(i, j, k)];
        const openvdb::Coord at(i, j, k);
        if (expected > floor) {
          ++active;
          EXPECT_TRUE(voxels.isValueOn(at)) << i << ' ' << j << ' ' << k;
          EXPECT_EQ(voxels.getValue(at), expected) << i << ' ' << j << ' ' << k;
        } else {
          EXPECT_FALSE(voxels.isValueOn(at)) << i << ' ' << j << ' ' << k;
          EXPECT_EQ(voxels.getValue(at), 0.0f);
        }
      }
  EXPECT_GT(active, 20);
  EXPECT_EQ(static_cast<std::int64_t>(vdb->activeVoxelCount()), active);
}

TEST(VdbVolume, RefusesAVolumeThatDoesNotFitItsGrid) {
  TempDir dir;
  const solvers::core::Summary s =
      WriteVdb((dir.path() / "v.vdb").string(), {4, 4, 4, 1.0}, Eigen::VectorXf::Zero(10));
  EXPECT_EQ(s.termination, solvers::core::Termination::kInvalidInput);
  EXPECT_FALSE(fs::exists(dir.path() / "v.vdb"));
}

// OpenVDB's exception, raised inside the module, comes back as a reason.
TEST(VdbVolume, AFileThatCannotBeWrittenIsAFailureWithOpenVdbsReason) {
  TempDir dir;
  const std::string path = (dir.path() / "missing" / "v.vdb").string();
  const solvers::core::Summary s = WriteVdb(path, {4, 4, 4, 1.0}, Eigen::VectorXf::Ones(64));
  EXPECT_EQ(s.termination, solvers::core::Termination::kFailure);
  EXPECT_NE(s.message.find("cannot write " + path + ": "), std::string::npos) << s.message;
  EXPECT_GT(s.message.size(), ("cannot write " + path + ": ").size() + 5) << s.message;
  EXPECT_FALSE(fs::exists(path));
}

}  // namespace
}  // namespace photorig::daemon
