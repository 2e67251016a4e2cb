// photorig_vdb.so: the OpenVDB side of WriteVdb (vdb_volume.h), loaded by
// vdb_volume.cpp when a solve writes volume.vdb (vdb_module_abi.h says why).

#include "vdb_module_abi.h"

#include <openvdb/openvdb.h>

#include <cstdio>
#include <exception>
#include <mutex>
#include <type_traits>

namespace {

using photorig::daemon::internal::VdbWriteFunction;

void Reason(char* reason, std::size_t size, const char* text) {
  if (size > 0) std::snprintf(reason, size, "%s", text);
}

}  // namespace

extern "C" int photorig_vdb_write_v1(const char* path, int nx, int ny, int nz, double voxel_mm, const float* sigma,
                                     float inactive_below, char* reason, std::size_t reason_size) {
  try {
    // Registers the grid types; OpenVDB asks for it once before any file work.
    static std::once_flag initialised;
    std::call_once(initialised, [] { openvdb::initialize(); });

    openvdb::FloatGrid::Ptr vdb = openvdb::FloatGrid::create(0.0f);
    vdb->setName("sigma");
    vdb->setGridClass(openvdb::GRID_FOG_VOLUME);
    vdb->insertMeta("units", openvdb::StringMetadata("sigma in 1/mm, voxel size in mm"));
    // Index (i, j, k) sits at VolumeGrid::VoxelCentre(i, j, k): scaled by the
    // voxel size, then shifted so that the grid is centred on the axis.
    openvdb::math::Transform::Ptr transform = openvdb::math::Transform::createLinearTransform(voxel_mm);
    transform->postTranslate(
        openvdb::Vec3d((0.5 - 0.5 * nx) * voxel_mm, (0.5 - 0.5 * ny) * voxel_mm, (0.5 - 0.5 * nz) * voxel_mm));
    vdb->setTransform(transform);
    openvdb::FloatGrid::Accessor voxels = vdb->getAccessor();
    const float* value = sigma;  // VolumeGrid::Index order: x fastest
    for (int k = 0; k < nz; ++k)
      for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i, ++value)
          if (*value > inactive_below) voxels.setValue(openvdb::Coord(i, j, k), *value);
    openvdb::io::File file(path);
    file.write({vdb});
    file.close();
    return 0;
  } catch (const std::exception& e) {
    Reason(reason, reason_size, e.what());
  } catch (...) {
    Reason(reason, reason_size, "OpenVDB failed without a reason");
  }
  return 1;
}

// The loader takes the entry point by this type; a signature that drifts
// from it fails to compile here rather than misreading arguments there.
static_assert(std::is_same_v<decltype(&photorig_vdb_write_v1), VdbWriteFunction>);
