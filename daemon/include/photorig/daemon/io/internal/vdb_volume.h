#pragma once
// A reconstructed volume as OpenVDB (Debian's libopenvdb-dev), the sparse
// format renderers (Blender, Houdini, Arnold) take for participating media:
// one FloatGrid named "sigma" holding the extinction coefficient in 1/mm,
// the voxel size in mm in its linear transform and the grid centred on the
// rotation axis as VolumeGrid places it (index (i, j, k) is voxel (i, j, k)
// of the volume), background 0. Voxels below a small tolerance stay
// inactive, so empty space costs nothing. OpenVDB itself is in the module
// photorig_vdb.so, loaded on the first call (src/io/vdb_module_abi.h), which
// CMake builds only where it finds OpenVDB (PHOTORIG_HAVE_OPENVDB); the
// header and its caller need no OpenVDB.

#include "photorig/solvers/core/summary.h"
#include "photorig/solvers/tomography/volume_grid.h"

#include <Eigen/Core>

#include <string>

namespace photorig::daemon {

struct VdbOptions {
  // Voxels whose sigma is below this fraction of the volume's largest are
  // left inactive (background 0). Default 1e-3: a thousandth of the peak,
  // under the noise of any reconstruction here.
  double inactive_below_fraction = 1e-3;
};

// Writes `sigma` (VolumeGrid::Index order) to `path`. kInvalidInput for sizes
// that do not match or a non-finite value; kFailure when the file cannot be
// written or the module does not load, with OpenVDB's or the loader's reason.
solvers::core::Summary WriteVdb(const std::string& path, const solvers::tomography::VolumeGrid& grid, const Eigen::VectorXf& sigma,
                          const VdbOptions& options = {});

}  // namespace photorig::daemon
