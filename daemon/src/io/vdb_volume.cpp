#include "photorig/daemon/io/internal/vdb_volume.h"

#include <openvdb/openvdb.h>

#include <cmath>
#include <mutex>

namespace photorig::daemon {

solvers::core::Summary WriteVdb(const std::string& path, const solvers::tomography::VolumeGrid& grid, const Eigen::VectorXf& sigma,
                          const VdbOptions& options) {
  solvers::core::Summary summary;
  if (sigma.size() != grid.voxels()) {
    summary.End(solvers::core::Termination::kInvalidInput, "the volume has " + std::to_string(sigma.size()) +
                                                         " values; the grid " + std::to_string(grid.voxels()));
    return summary;
  }
  if (!sigma.allFinite()) {
    summary.End(solvers::core::Termination::kInvalidInput, "the volume holds a non-finite value");
    return summary;
  }
  // Registers the grid types; OpenVDB asks for it once before any file work.
  static std::once_flag initialised;
  std::call_once(initialised, [] { openvdb::initialize(); });

  const auto floor = static_cast<float>(options.inactive_below_fraction * std::max(0.0f, sigma.maxCoeff()));
  openvdb::FloatGrid::Ptr vdb = openvdb::FloatGrid::create(0.0f);
  vdb->setName("sigma");
  vdb->setGridClass(openvdb::GRID_FOG_VOLUME);
  vdb->insertMeta("units", openvdb::StringMetadata("sigma in 1/mm, voxel size in mm"));
  // Index (i, j, k) sits at VolumeGrid::VoxelCentre(i, j, k): scaled by the
  // voxel size, then shifted so that the grid is centred on the axis.
  openvdb::math::Transform::Ptr transform = openvdb::math::Transform::createLinearTransform(grid.voxel_mm);
  transform->postTranslate(openvdb::Vec3d((0.5 - 0.5 * grid.nx) * grid.voxel_mm, (0.5 - 0.5 * grid.ny) * grid.voxel_mm,
                                          (0.5 - 0.5 * grid.nz) * grid.voxel_mm));
  vdb->setTransform(transform);
  openvdb::FloatGrid::Accessor voxels = vdb->getAccessor();
  for (int k = 0; k < grid.nz; ++k)
    for (int j = 0; j < grid.ny; ++j)
      for (int i = 0; i < grid.nx; ++i) {
        const float value = sigma[grid.Index(i, j, k)];
        if (value > floor) voxels.setValue(openvdb::Coord(i, j, k), value);
      }
  try {
    openvdb::io::File file(path);
    file.write({vdb});
    file.close();
  } catch (const openvdb::Exception& e) {
    summary.End(solvers::core::Termination::kFailure, "cannot write " + path + ": " + e.what());
    return summary;
  }
  summary.End(solvers::core::Termination::kSuccess, "");
  return summary;
}

}  // namespace photorig::daemon
