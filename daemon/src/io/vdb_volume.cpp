#include "photorig/daemon/io/internal/vdb_volume.h"

#include "vdb_module_abi.h"

#include <dlfcn.h>

#include <algorithm>
#include <string>

namespace photorig::daemon {
namespace {

// The module's entry point, loaded once per process. The module stays loaded
// (OpenVDB's static state is not made to be unloaded). The dynamic loader
// finds it through the program's RUNPATH: the build tree's lib/photorig, or
// once installed the module folder relative to the program (CMakeLists.txt).
struct VdbModule {
  internal::VdbWriteFunction write = nullptr;
  std::string error;  // why `write` is null
};

const VdbModule& LoadVdbModule() {
  static const VdbModule module = [] {
    VdbModule loaded;
    void* handle = dlopen(internal::kVdbModuleFile, RTLD_NOW | RTLD_LOCAL);
    if (handle) loaded.write = reinterpret_cast<internal::VdbWriteFunction>(dlsym(handle, internal::kVdbWriteSymbol));
    if (!loaded.write) {
      const char* why = dlerror();
      loaded.error = std::string("the OpenVDB writer ") + internal::kVdbModuleFile + " did not load (" +
                     (why ? why : "no reason given") +
                     "); reinstall photorig, or run it from the build tree that built the module";
    }
    return loaded;
  }();
  return module;
}

}  // namespace

solvers::core::Summary WriteVdb(const std::string& path, const solvers::tomography::VolumeGrid& grid,
                                const Eigen::VectorXf& sigma, const VdbOptions& options) {
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
  const VdbModule& module = LoadVdbModule();
  if (!module.write) {
    summary.End(solvers::core::Termination::kFailure, "cannot write " + path + ": " + module.error);
    return summary;
  }
  const auto floor = static_cast<float>(options.inactive_below_fraction * std::max(0.0f, sigma.maxCoeff()));
  char reason[512] = {};
  if (module.write(path.c_str(), grid.nx, grid.ny, grid.nz, grid.voxel_mm, sigma.data(), floor, reason,
                   sizeof reason) != 0) {
    summary.End(solvers::core::Termination::kFailure, "cannot write " + path + ": " + reason);
    return summary;
  }
  summary.End(solvers::core::Termination::kSuccess, "");
  return summary;
}

}  // namespace photorig::daemon
