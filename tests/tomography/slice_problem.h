#pragma once
// A one-slice Shepp-Logan problem: parallel views of the 2D phantom, whose
// exact line integrals (not the projector's) make b, and its rasterised
// ground truth.

#include "photorig/sim/phantom.h"
#include "photorig/solvers/tomography/projector.h"
#include "photorig/solvers/tomography/reconstruct.h"

#include <Eigen/Core>

#include <memory>

namespace photorig::solvers::tomography::testing_support {

struct SliceProblem {
  VolumeGrid grid;
  Geometry geometry;
  sim::Phantom phantom;
  Eigen::VectorXf truth;
  std::vector<std::uint8_t> inside;  // voxels inside the reconstruction circle
  std::unique_ptr<Projector> projector;

  SliceProblem(int n, int views, double span_deg = 180.0, double cor_offset_mm = 0.0,
               Interpolation interpolation = Interpolation::kSiddon)
      : grid{n, n, 1, 32.0 / n}, phantom(sim::Phantom::SheppLogan2d(16.0, 0.1)) {
    geometry.detector_cols = n;
    geometry.detector_rows = 1;
    geometry.pixel_mm = grid.voxel_mm;
    geometry.angles_rad = EvenAngles(views, span_deg);
    geometry.cor_offset_mm = cor_offset_mm;
    const std::vector<float> raster = phantom.Rasterise(grid, 4);
    truth = Eigen::Map<const Eigen::VectorXf>(raster.data(), static_cast<Eigen::Index>(raster.size()));
    inside.resize(raster.size());
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        inside[grid.Index(i, j, 0)] = grid.VoxelCentre(i, j, 0).head<2>().norm() < 0.5 * n * grid.voxel_mm;
    ProjectorOptions options;
    options.interpolation = interpolation;
    MakeProjector(grid, geometry, options, &projector);
  }

  Absorbance Exact() const {
    const std::vector<float> b = sim::ProjectPhantom(phantom, geometry);
    return {Eigen::Map<const Eigen::VectorXf>(b.data(), static_cast<Eigen::Index>(b.size())), {}, {}};
  }

  // Relative L2 error inside the reconstruction circle.
  double Error(const Eigen::VectorXf& x) const {
    double diff = 0.0, norm = 0.0;
    for (std::int64_t i = 0; i < x.size(); ++i)
      if (inside[i]) {
        diff += (x[i] - truth[i]) * (x[i] - truth[i]);
        norm += truth[i] * truth[i];
      }
    return std::sqrt(diff / norm);
  }
};

}  // namespace photorig::solvers::tomography::testing_support
