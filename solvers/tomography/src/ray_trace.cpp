#include "photorig/solvers/tomography/ray_trace.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace photorig::solvers::tomography {

namespace {

constexpr double kParallelEps = 1e-12;

// The ray's parameter interval inside the grid's box (slab test); false when it misses.
bool ClipToBox(const Eigen::Vector3d& half, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double* t0,
               double* t1) {
  *t0 = -std::numeric_limits<double>::infinity();
  *t1 = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (std::abs(d[a]) < kParallelEps) {
      if (o[a] <= -half[a] || o[a] >= half[a]) return false;
      continue;
    }
    double ta = (-half[a] - o[a]) / d[a], tb = (half[a] - o[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    *t0 = std::max(*t0, ta);
    *t1 = std::min(*t1, tb);
  }
  return *t1 > *t0;
}

void Siddon(const VolumeGrid& grid, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t0, double t1,
            std::vector<RayWeight>* out) {
  const int n[3] = {grid.nx, grid.ny, grid.nz};
  const Eigen::Vector3d half = grid.half_extent_mm();
  const double v = grid.voxel_mm;
  // The voxel at the middle of the first step decides the start, so that an
  // entry exactly on a face lands inside the grid.
  const Eigen::Vector3d entry = o + t0 * d;
  int idx[3], step[3];
  double t_max[3], t_delta[3];
  for (int a = 0; a < 3; ++a) {
    idx[a] = std::clamp(static_cast<int>(std::floor((entry[a] + half[a]) / v)), 0, n[a] - 1);
    if (d[a] > kParallelEps) {
      step[a] = 1;
      t_max[a] = ((idx[a] + 1) * v - half[a] - o[a]) / d[a];
      t_delta[a] = v / d[a];
    } else if (d[a] < -kParallelEps) {
      step[a] = -1;
      t_max[a] = (idx[a] * v - half[a] - o[a]) / d[a];
      t_delta[a] = -v / d[a];
    } else {
      step[a] = 0;
      t_max[a] = std::numeric_limits<double>::infinity();
      t_delta[a] = 0.0;
    }
  }
  double t = t0;
  for (;;) {
    const int a = t_max[0] < t_max[1] ? (t_max[0] < t_max[2] ? 0 : 2) : (t_max[1] < t_max[2] ? 1 : 2);
    const double t_next = std::min(t_max[a], t1);
    if (t_next > t)
      out->push_back({static_cast<std::int32_t>(grid.Index(idx[0], idx[1], idx[2])), static_cast<float>(t_next - t)});
    t = std::max(t, t_next);
    if (t >= t1) break;
    idx[a] += step[a];
    if (idx[a] < 0 || idx[a] >= n[a]) break;
    t_max[a] += t_delta[a];
  }
}

void Joseph(const VolumeGrid& grid, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
            std::vector<RayWeight>* out) {
  const int n[3] = {grid.nx, grid.ny, grid.nz};
  const Eigen::Vector3d half = grid.half_extent_mm();
  const double v = grid.voxel_mm;
  int a = 0;
  for (int k = 1; k < 3; ++k)
    if (std::abs(d[k]) > std::abs(d[a])) a = k;
  const int b = (a + 1) % 3, c = (a + 2) % 3;
  // Each layer along the dominant axis stands for v / |d_a| of path.
  const double length = v / std::abs(d[a]);
  for (int layer = 0; layer < n[a]; ++layer) {
    const double plane = (layer + 0.5) * v - half[a];
    const double t = (plane - o[a]) / d[a];
    const double pb = o[b] + t * d[b], pc = o[c] + t * d[c];
    // Only where the ray is inside the box: zero padding would leak weight outside it.
    if (pb < -half[b] || pb > half[b] || pc < -half[c] || pc > half[c]) continue;
    const double fb = (pb + half[b]) / v - 0.5, fc = (pc + half[c]) / v - 0.5;
    const int b0 = static_cast<int>(std::floor(fb)), c0 = static_cast<int>(std::floor(fc));
    const double wb = fb - b0, wc = fc - c0;
    for (int jc = 0; jc < 2; ++jc)
      for (int jb = 0; jb < 2; ++jb) {
        int idx[3];
        idx[a] = layer;
        idx[b] = b0 + jb;
        idx[c] = c0 + jc;
        const double w = (jb ? wb : 1.0 - wb) * (jc ? wc : 1.0 - wc);
        if (w <= 0.0) continue;
        // At the edge layer the missing neighbour's share goes to the one inside,
        // so that the weights still sum to the path length.
        idx[b] = std::clamp(idx[b], 0, n[b] - 1);
        idx[c] = std::clamp(idx[c], 0, n[c] - 1);
        const auto voxel = static_cast<std::int32_t>(grid.Index(idx[0], idx[1], idx[2]));
        if (!out->empty() && out->back().voxel == voxel)
          out->back().weight_mm += static_cast<float>(w * length);
        else
          out->push_back({voxel, static_cast<float>(w * length)});
      }
  }
  // A clamped neighbour can repeat a voxel out of order: merge repeats.
  std::sort(out->begin(), out->end(), [](const RayWeight& l, const RayWeight& r) { return l.voxel < r.voxel; });
  std::size_t kept = 0;
  for (std::size_t i = 0; i < out->size(); ++i) {
    if (kept > 0 && (*out)[kept - 1].voxel == (*out)[i].voxel)
      (*out)[kept - 1].weight_mm += (*out)[i].weight_mm;
    else
      (*out)[kept++] = (*out)[i];
  }
  out->resize(kept);
}

}  // namespace

void TraceRay(const VolumeGrid& grid, const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
              Interpolation interpolation, std::vector<RayWeight>* weights) {
  weights->clear();
  double t0 = 0.0, t1 = 0.0;
  if (!ClipToBox(grid.half_extent_mm(), origin, direction, &t0, &t1)) return;
  if (interpolation == Interpolation::kSiddon)
    Siddon(grid, origin, direction, t0, t1, weights);
  else
    Joseph(grid, origin, direction, weights);
}

void TraceRayInSlices(const VolumeGrid& grid, int first_slice, int slices, const Eigen::Vector3d& origin,
                      const Eigen::Vector3d& direction, Interpolation interpolation, std::vector<RayWeight>* weights) {
  weights->clear();
  double t0 = 0.0, t1 = 0.0;
  const Eigen::Vector3d half = grid.half_extent_mm();
  if (!ClipToBox(half, origin, direction, &t0, &t1)) return;
  // Most rays of a scan run nearly across z and miss most slabs: skip those
  // without tracing. The margin of a voxel covers Joseph's neighbours.
  const double z0 = origin.z() + t0 * direction.z(), z1 = origin.z() + t1 * direction.z();
  const double low = first_slice * grid.voxel_mm - half.z(), high = (first_slice + slices) * grid.voxel_mm - half.z();
  if (std::max(z0, z1) < low - grid.voxel_mm || std::min(z0, z1) > high + grid.voxel_mm) return;
  TraceRay(grid, origin, direction, interpolation, weights);
  const std::int64_t per_slice = static_cast<std::int64_t>(grid.nx) * grid.ny;
  const std::int64_t begin = first_slice * per_slice, end = (first_slice + slices) * per_slice;
  std::size_t kept = 0;
  for (const RayWeight& w : *weights)
    if (w.voxel >= begin && w.voxel < end)
      (*weights)[kept++] = {static_cast<std::int32_t>(w.voxel - begin), w.weight_mm};
  weights->resize(kept);
}

}  // namespace photorig::solvers::tomography
