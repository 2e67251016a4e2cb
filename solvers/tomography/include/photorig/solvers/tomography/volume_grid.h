#pragma once
// The voxel grid a reconstruction fills. Units: voxel_mm in millimetres, the
// values it holds (sigma) in 1/mm, so that a line integral through it (b) has
// no unit. The grid is centred on the origin, which lies on the rotation axis
// (the z axis); voxel (i, j, k) has its centre at
//   ((i + 0.5 - nx/2) voxel_mm, (j + 0.5 - ny/2) voxel_mm, (k + 0.5 - nz/2) voxel_mm)
// and is stored at Index(i, j, k): x fastest, then y, then z.

#include <Eigen/Core>

#include <cstdint>
#include <string>

namespace photorig::solvers::tomography {

struct VolumeGrid {
  int nx = 64;
  int ny = 64;
  int nz = 64;            // 1 for a single slice (a 2D problem)
  double voxel_mm = 0.5;  // cubic voxels

  bool IsValid(std::string* why) const;
  std::int64_t voxels() const { return static_cast<std::int64_t>(nx) * ny * nz; }
  std::int64_t Index(int i, int j, int k) const { return (static_cast<std::int64_t>(k) * ny + j) * nx + i; }
  Eigen::Vector3d half_extent_mm() const { return 0.5 * voxel_mm * Eigen::Vector3d(nx, ny, nz); }
  Eigen::Vector3d VoxelCentre(int i, int j, int k) const;
};

}  // namespace photorig::solvers::tomography
