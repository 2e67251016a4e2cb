#include "photorig/solvers/tomography/volume_grid.h"
#include "photorig/solvers/core/summary.h"

#include <cmath>
#include <limits>

namespace photorig::solvers::tomography {

bool VolumeGrid::IsValid(std::string* why) const {
  if (nx < 1 || ny < 1 || nz < 1) return core::Refuse(why, "a volume grid needs at least one voxel along x, y and z");
  if (!(voxel_mm > 0) || !std::isfinite(voxel_mm)) return core::Refuse(why, "voxel_mm must be finite and > 0");
  // Rows of W index voxels with 32-bit integers.
  if (voxels() > std::numeric_limits<std::int32_t>::max()) return core::Refuse(why, "the grid has more than 2^31 voxels");
  return true;
}

Eigen::Vector3d VolumeGrid::VoxelCentre(int i, int j, int k) const {
  return voxel_mm * Eigen::Vector3d(i + 0.5 - 0.5 * nx, j + 0.5 - 0.5 * ny, k + 0.5 - 0.5 * nz);
}

}  // namespace photorig::solvers::tomography
