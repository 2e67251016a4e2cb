#pragma once
// A participating medium (absorbing, non-scattering) on a voxel grid, seen in
// transmission against a uniform backlight:
//   L(pixel) = L_backlight * exp(-tau),   tau = integral of sigma(s) ds along the pixel's ray.
// tau is also the ground truth for tomography.

#include "photorig/sim/camera_model.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace photorig::sim {

struct DensityGrid {
  int nx = 0, ny = 0, nz = 0;
  double voxel_mm = 0.5;            // cubic voxels; the grid is centred on the origin
  std::vector<float> sigma_per_mm;  // extinction coefficient, x fastest, then y, then z

  bool IsValid(std::string* why) const;
  // Trilinear interpolation between voxel centres; 0 outside the grid.
  double Sample(const Eigen::Vector3d& point_mm) const;
  Eigen::Vector3d half_extent_mm() const { return 0.5 * voxel_mm * Eigen::Vector3d(nx, ny, nz); }

  // A phantom: three Gaussian blobs of peak `peak_sigma_per_mm` in a cube of
  // side `extent_mm` sampled with n^3 voxels.
  static DensityGrid Blobs(double extent_mm, int n, double peak_sigma_per_mm);
};

// Per-pixel tau (CV_32F) by midpoint-rule ray marching of step `step_mm`
// (0: half a voxel) across the grid's bounding box.
cv::Mat LineIntegrals(const DensityGrid& grid, const CameraModel& camera, double step_mm = 0.0);

}  // namespace photorig::sim
