#pragma once
// A volume as NRRD (teem's "nearly raw raster data"): a short text header,
// then raw little-endian float32, x fastest. The header states the spacing in
// mm and that the values are sigma in 1/mm; 3D Slicer, ParaView and teem's
// unu read it.

#include "photorig/solvers/core/summary.h"
#include "photorig/solvers/tomography/volume_grid.h"

#include <Eigen/Core>

#include <string>

namespace photorig::solvers::tomography {

solvers::core::Summary WriteNrrd(const std::string& path, const VolumeGrid& grid, const Eigen::VectorXf& sigma);
// Reads what WriteNrrd writes (3D float32, raw, either endianness); anything
// else ends kInvalidInput with the reason.
solvers::core::Summary ReadNrrd(const std::string& path, VolumeGrid* grid, Eigen::VectorXf* sigma);

}  // namespace photorig::solvers::tomography
