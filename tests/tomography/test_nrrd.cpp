#include "photorig/solvers/tomography/nrrd.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace photorig::solvers::tomography {
namespace {

TEST(Nrrd, WritesAHeaderAndRawFloatsThatReadBack) {
  const VolumeGrid grid{5, 4, 3, 0.25};
  Eigen::VectorXf sigma(grid.voxels());
  for (std::int64_t i = 0; i < sigma.size(); ++i) sigma[i] = 0.01f * static_cast<float>(i) - 0.2f;
  const std::string path = (std::filesystem::temp_directory_path() / "photorig_test_volume.nrrd").string();
  ASSERT_EQ(WriteNrrd(path, grid, sigma).termination, solvers::core::Termination::kSuccess);

  std::ifstream in(path, std::ios::binary);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto end = text.find("\n\n");
  ASSERT_NE(end, std::string::npos);
  EXPECT_EQ(text.size() - (end + 2), sizeof(float) * grid.voxels()) << "raw float32 after the blank line";
  EXPECT_NE(text.find("sizes: 5 4 3\n"), std::string::npos);
  EXPECT_NE(text.find("endian: little\n"), std::string::npos);

  VolumeGrid read;
  Eigen::VectorXf back;
  ASSERT_EQ(ReadNrrd(path, &read, &back).termination, solvers::core::Termination::kSuccess);
  EXPECT_EQ(read.nx, 5);
  EXPECT_EQ(read.ny, 4);
  EXPECT_EQ(read.nz, 3);
  EXPECT_DOUBLE_EQ(read.voxel_mm, 0.25);
  EXPECT_EQ(back, sigma);
  std::filesystem::remove(path);
}

TEST(Nrrd, RefusesWhatItCannotRead) {
  VolumeGrid grid;
  Eigen::VectorXf sigma;
  EXPECT_EQ(ReadNrrd("/nonexistent/volume.nrrd", &grid, &sigma).termination, solvers::core::Termination::kInvalidInput);
  const std::string path = (std::filesystem::temp_directory_path() / "photorig_test_gzip.nrrd").string();
  std::ofstream(path) << "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nencoding: gzip\n\n";
  const solvers::core::Summary s = ReadNrrd(path, &grid, &sigma);
  EXPECT_EQ(s.termination, solvers::core::Termination::kInvalidInput);
  EXPECT_NE(s.message.find("gzip"), std::string::npos);
  EXPECT_EQ(WriteNrrd(path, {2, 2, 2, 1.0}, Eigen::VectorXf(3)).termination, solvers::core::Termination::kInvalidInput);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace photorig::solvers::tomography
