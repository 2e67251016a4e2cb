# OpenCV as Debian 12 installs it. Its OpenCVConfig.cmake comes only with
# libopencv-dev, which pulls in every module's -dev package (viz, dnn,
# videoio, ...): a fifth of the whole tree's packages. The demo's package set
# (scripts/install-deps.sh demo) installs the modules it uses one by one, so
# where that config is missing each installed module is found here by its
# header and library, as the imported target opencv_<module> the config
# would define. Where the config is present it is used as it stands.
find_package(OpenCV ${OpenCV_FIND_VERSION} CONFIG QUIET COMPONENTS ${OpenCV_FIND_COMPONENTS})
if(OpenCV_FOUND)
  return()
endif()

find_path(OpenCV_INCLUDE_DIR opencv2/core/version.hpp PATH_SUFFIXES opencv4)
if(OpenCV_INCLUDE_DIR)
  file(STRINGS "${OpenCV_INCLUDE_DIR}/opencv2/core/version.hpp" version_lines
       REGEX "^#define CV_VERSION_(MAJOR|MINOR|REVISION) +[0-9]+")
  foreach(part MAJOR MINOR REVISION)
    string(REGEX REPLACE ".*#define CV_VERSION_${part} +([0-9]+).*" "\\1" OpenCV_VERSION_${part} "${version_lines}")
  endforeach()
  set(OpenCV_VERSION "${OpenCV_VERSION_MAJOR}.${OpenCV_VERSION_MINOR}.${OpenCV_VERSION_REVISION}")
endif()

# Every installed module, as the config does: targets link modules they were
# not asked for (sim/ links opencv_calib3d). The demo's modules are enough.
set(OpenCV_LIBS "")
foreach(module core imgproc imgcodecs calib3d mcc)
  find_library(OpenCV_${module}_LIBRARY opencv_${module})
  set(header "${OpenCV_INCLUDE_DIR}/opencv2/${module}.hpp")
  if(OpenCV_INCLUDE_DIR AND OpenCV_${module}_LIBRARY AND EXISTS "${header}")
    set(OpenCV_${module}_FOUND TRUE)
    list(APPEND OpenCV_LIBS opencv_${module})
    if(NOT TARGET opencv_${module})
      add_library(opencv_${module} SHARED IMPORTED)
      set_target_properties(opencv_${module} PROPERTIES
        IMPORTED_LOCATION "${OpenCV_${module}_LIBRARY}" INTERFACE_INCLUDE_DIRECTORIES "${OpenCV_INCLUDE_DIR}")
      if(NOT module STREQUAL "core")
        set_target_properties(opencv_${module} PROPERTIES INTERFACE_LINK_LIBRARIES opencv_core)
      endif()
    endif()
  endif()
endforeach()
set(OpenCV_INCLUDE_DIRS "${OpenCV_INCLUDE_DIR}")

include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(OpenCV REQUIRED_VARS OpenCV_INCLUDE_DIR OpenCV_LIBS VERSION_VAR OpenCV_VERSION
                                  HANDLE_COMPONENTS)
