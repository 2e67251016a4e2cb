# Precompiled headers for the libraries and programs the demo builds
# (docs/building.md). Nearly every translation unit parses the same standard,
# Eigen, OpenCV and JSON headers; parsing them was 40 % of a cold build's
# compiler time. Each target gets a header of its own, compiled with its own
# flags (-O3, -fopenmp, -fno-math-errno, -fPIC differ), so no PCH is reused
# where its macros could differ.
#
# Only third-party headers that no source configures with a macro (tiny_gltf.h
# is, in gltf_export.cpp; it stays out). Off by default with a compiler
# launcher: ccache caches nothing that uses a PCH unless its sloppiness allows
# it, and a warm cache is faster than a PCH.
if(CMAKE_CXX_COMPILER_LAUNCHER)
  set(photorig_pch_default OFF)
else()
  set(photorig_pch_default ON)
endif()
option(PHOTORIG_PCH "Precompile the heavy third-party headers per target" ${photorig_pch_default})

# Standard headers most translation units include.
set(PHOTORIG_PCH_STD <algorithm> <array> <chrono> <cmath> <cstdint> <functional> <map> <memory> <mutex>
    <optional> <string> <string_view> <utility> <vector>)

# photorig_precompile_headers(target header...): the standard set, then the
# given headers, as target's private PCH.
function(photorig_precompile_headers target)
  if(PHOTORIG_PCH)
    target_precompile_headers(${target} PRIVATE ${ARGN} ${PHOTORIG_PCH_STD})
  endif()
endfunction()
