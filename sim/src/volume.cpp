#include "photorig/sim/volume.h"

#include "photorig/solvers/core/summary.h"

#include <algorithm>
#include <cmath>

namespace photorig::sim {
using solvers::core::Refuse;

bool DensityGrid::IsValid(std::string* why) const {
  if (nx < 1 || ny < 1 || nz < 1) return Refuse(why, "a density grid needs at least one voxel");
  if (!(voxel_mm > 0)) return Refuse(why, "voxel_mm must be > 0");
  if (sigma_per_mm.size() != static_cast<std::size_t>(nx) * ny * nz) return Refuse(why, "density grid size mismatch");
  for (float s : sigma_per_mm)
    if (!(s >= 0)) return Refuse(why, "densities must be finite and >= 0");
  return true;
}

double DensityGrid::Sample(const Eigen::Vector3d& p) const {
  // Continuous voxel coordinates with voxel centres at integers.
  const double fx = p.x() / voxel_mm + 0.5 * nx - 0.5, fy = p.y() / voxel_mm + 0.5 * ny - 0.5,
               fz = p.z() / voxel_mm + 0.5 * nz - 0.5;
  if (fx < -0.5 || fy < -0.5 || fz < -0.5 || fx > nx - 0.5 || fy > ny - 0.5 || fz > nz - 0.5) return 0.0;
  const int x0 = static_cast<int>(std::floor(fx)), y0 = static_cast<int>(std::floor(fy)),
            z0 = static_cast<int>(std::floor(fz));
  const double tx = fx - x0, ty = fy - y0, tz = fz - z0;
  double sum = 0.0;
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 2; ++i) {
        const int x = std::clamp(x0 + i, 0, nx - 1), y = std::clamp(y0 + j, 0, ny - 1), z = std::clamp(z0 + k, 0, nz - 1);
        const double w = (i ? tx : 1 - tx) * (j ? ty : 1 - ty) * (k ? tz : 1 - tz);
        sum += w * sigma_per_mm[(static_cast<std::size_t>(z) * ny + y) * nx + x];
      }
  return sum;
}

DensityGrid DensityGrid::Blobs(double extent_mm, int n, double peak_sigma_per_mm) {
  DensityGrid grid;
  grid.nx = grid.ny = grid.nz = n;
  grid.voxel_mm = extent_mm / n;
  grid.sigma_per_mm.resize(static_cast<std::size_t>(n) * n * n);
  struct Blob {
    double x, y, z, s, peak;
  };
  const double e = extent_mm;
  const Blob blobs[] = {{-0.15 * e, 0.1 * e, 0.0, 0.12 * e, 1.0},
                        {0.18 * e, -0.12 * e, 0.1 * e, 0.08 * e, 0.7},
                        {0.05 * e, 0.2 * e, -0.15 * e, 0.05 * e, 0.5}};
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const double x = (i + 0.5 - 0.5 * n) * grid.voxel_mm, y = (j + 0.5 - 0.5 * n) * grid.voxel_mm,
                     z = (k + 0.5 - 0.5 * n) * grid.voxel_mm;
        double sigma = 0.0;
        for (const Blob& b : blobs) {
          const double d2 = (x - b.x) * (x - b.x) + (y - b.y) * (y - b.y) + (z - b.z) * (z - b.z);
          sigma += b.peak * peak_sigma_per_mm * std::exp(-d2 / (2 * b.s * b.s));
        }
        grid.sigma_per_mm[(static_cast<std::size_t>(k) * n + j) * n + i] = static_cast<float>(sigma);
      }
  return grid;
}

cv::Mat LineIntegrals(const DensityGrid& grid, const CameraModel& camera, double step_mm) {
  cv::Mat tau = cv::Mat::zeros(camera.height, camera.width, CV_32F);
  const double step = step_mm > 0 ? step_mm : 0.5 * grid.voxel_mm;
  const Eigen::Vector3d half = grid.half_extent_mm();
#pragma omp parallel for schedule(dynamic, 8)
  for (int r = 0; r < camera.height; ++r)
    for (int c = 0; c < camera.width; ++c) {
      Eigen::Vector3d origin, dir;
      camera.Ray(c, r, &origin, &dir);
      // Slab intersection with the grid's box.
      double t0 = -1e300, t1 = 1e300;
      for (int a = 0; a < 3; ++a) {
        if (std::abs(dir[a]) < 1e-15) {
          if (std::abs(origin[a]) > half[a]) t0 = 1e300;
          continue;
        }
        double ta = (-half[a] - origin[a]) / dir[a], tb = (half[a] - origin[a]) / dir[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
      }
      if (!(t1 > t0)) continue;
      // Midpoint rule with a whole number of steps across the box.
      const int steps = std::max(1, static_cast<int>(std::ceil((t1 - t0) / step)));
      const double dt = (t1 - t0) / steps;
      double sum = 0.0;
      for (int i = 0; i < steps; ++i) sum += grid.Sample(origin + (t0 + (i + 0.5) * dt) * dir);
      tau.at<float>(r, c) = static_cast<float>(sum * dt);
    }
  return tau;
}

}  // namespace photorig::sim
