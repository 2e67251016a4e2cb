#pragma once
// One row of W: the weights (in mm) of the voxels a ray crosses, so that
// sum of weight * sigma approximates the ray's line integral b.
//
//   kSiddon: the exact length of the ray inside each voxel (Siddon 1985,
//            "Fast calculation of the exact radiological path for a
//            three-dimensional CT array", Med. Phys. 12(2); traversed
//            incrementally as Amanatides & Woo 1987). The lengths sum to the
//            ray's chord through the grid.
//   kJoseph: the ray sampled once per voxel layer along its dominant axis,
//            with bilinear weights in the other two (Joseph 1982, "An improved
//            algorithm for reprojecting rays through pixel images", IEEE TMI
//            1(3)). Smoother rows and fewer aliasing artefacts; the weights
//            also sum to the chord inside the grid, up to its edge layers.

#include "photorig/solvers/core/names.h"
#include "photorig/solvers/tomography/volume_grid.h"

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

namespace photorig::solvers::tomography {

enum class Interpolation { kSiddon, kJoseph };
inline constexpr core::NameTable<Interpolation, 2> kInterpolationNames = {
    {{Interpolation::kJoseph, "joseph"}, {Interpolation::kSiddon, "siddon"}}};
inline std::optional<Interpolation> ParseInterpolation(std::string_view name) {
  return core::ParseName(kInterpolationNames, name);
}
inline const char* InterpolationName(Interpolation interpolation) {
  return core::NameOf(kInterpolationNames, interpolation);
}

struct RayWeight {
  std::int32_t voxel;  // VolumeGrid::Index
  float weight_mm;
};

// Replaces *weights with the ray's (origin, unit direction) weights through
// `grid`; empty when the ray misses it. Voxels appear at most once.
void TraceRay(const VolumeGrid& grid, const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
              Interpolation interpolation, std::vector<RayWeight>* weights);

// The same ray's weights on the z-slices [first_slice, first_slice + slices)
// of `grid` only, indexed in that slab (a grid of nx x ny x slices): the
// whole grid's row cut to the slab's voxels, never the row of a smaller grid,
// so that Joseph's weights across the slab's faces, and a ray lying exactly
// on a face, stay those of the whole grid and the slabs' rows add up to it.
void TraceRayInSlices(const VolumeGrid& grid, int first_slice, int slices, const Eigen::Vector3d& origin,
                      const Eigen::Vector3d& direction, Interpolation interpolation, std::vector<RayWeight>* weights);

}  // namespace photorig::solvers::tomography
