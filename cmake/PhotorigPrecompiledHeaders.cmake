# Precompiled headers for the libraries and programs the demo builds (README.md,
# "Set-up on a fresh Debian 12 machine"). Nearly every translation unit parses
# the same standard, Eigen, OpenCV and JSON headers; precompiled, they save a
# sixth of the compiler's time in a cold build. Each target precompiles its
# own, with its own flags (-O3, -fopenmp, -fno-math-errno and -fPIC differ
# between targets), so no PCH is used where its macros could differ.
#
# Only third-party headers that no source configures with a macro (tiny_gltf.h
# is, in gltf_export.cpp; it stays out). Off by default with a compiler
# launcher: ccache compiles files that use a PCH without caching them unless
# its sloppiness allows PCHs, and a warm cache is faster than a PCH.
if(CMAKE_CXX_COMPILER_LAUNCHER)
  set(photorig_pch_default OFF)
else()
  set(photorig_pch_default ON)
endif()
option(PHOTORIG_PCH "Precompile the heavy third-party headers per target" ${photorig_pch_default})

# Standard headers most translation units include.
set(PHOTORIG_PCH_STD <algorithm> <array> <chrono> <cmath> <cstdint> <functional> <map> <memory> <mutex>
    <optional> <string> <string_view> <utility> <vector>)

# photorig_precompile_headers(target header...): the given headers in their
# order (pybind11's come first), then the standard set, as target's private PCH.
function(photorig_precompile_headers target)
  if(PHOTORIG_PCH)
    target_precompile_headers(${target} PRIVATE ${ARGN} ${PHOTORIG_PCH_STD})
  endif()
endfunction()
