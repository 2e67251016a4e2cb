#pragma once
// What the OpenVDB writer module (photorig_vdb.so, vdb_module.cpp) and its
// loader (vdb_volume.cpp) agree on. The module is loaded with dlopen when a
// solve writes volume.vdb, so that no other process maps OpenVDB and the
// libraries it pulls in (its relocations were most of every process's
// start-up). A plain C entry point: nothing of C++'s ABI crosses it, and the
// version in the symbol's name makes a stale module fail to load rather
// than misread its arguments.

#include <cstddef>

namespace photorig::daemon::internal {

inline constexpr char kVdbModuleFile[] = "photorig_vdb.so";
inline constexpr char kVdbWriteSymbol[] = "photorig_vdb_write_v1";

// Writes a FloatGrid "sigma" (vdb_volume.h) of nx * ny * nz voxels of edge
// voxel_mm from `sigma`, x fastest, then y, then z (VolumeGrid::Index);
// values at or below inactive_below are left as the background (0). Returns 0, or non-zero
// with a reason (NUL-terminated, cut to reason_size) in `reason`. Never throws.
using VdbWriteFunction = int (*)(const char* path, int nx, int ny, int nz, double voxel_mm, const float* sigma,
                                 float inactive_below, char* reason, std::size_t reason_size);

}  // namespace photorig::daemon::internal
