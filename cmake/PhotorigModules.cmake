# Adds every immediate subdirectory of the current source directory that has a
# CMakeLists.txt, in name order. New modules (a driver, a solver, a test area)
# join the build by existing; no parent list needs editing.
#
# PHOTORIG_SKIP_MODULES (a list of directory names, e.g. "aravis;v4l2") leaves
# modules out, for building on a machine without one of their libraries.
# Leaving out aravis, v4l2, gpio, usbrelay or gige works: targets and tests
# that need them check if(TARGET ...), code checks photorig/config/modules.h,
# and a rig naming a missing driver fails to load, saying so. modbus and
# motion cannot be left out (rigconfig/CMakeLists.txt says why).
set(PHOTORIG_SKIP_MODULES "" CACHE STRING "module directory names to leave out of the build")

function(photorig_add_module_subdirectories)
  file(GLOB children LIST_DIRECTORIES true CONFIGURE_DEPENDS "${CMAKE_CURRENT_SOURCE_DIR}/*")
  list(SORT children)
  foreach(child IN LISTS children)
    get_filename_component(name "${child}" NAME)
    if(name IN_LIST PHOTORIG_SKIP_MODULES)
      message(STATUS "photorig: skipping module ${child}")
    elseif(IS_DIRECTORY "${child}" AND EXISTS "${child}/CMakeLists.txt")
      add_subdirectory("${child}")
    endif()
  endforeach()
endfunction()

# Sets POSITION_INDEPENDENT_CODE on every static library defined in `directory`
# and below: what a shared object (the Python module) needs of what it links.
function(photorig_static_libraries_position_independent directory)
  get_property(targets DIRECTORY ${directory} PROPERTY BUILDSYSTEM_TARGETS)
  foreach(target IN LISTS targets)
    get_target_property(type ${target} TYPE)
    if(type STREQUAL "STATIC_LIBRARY")
      set_target_properties(${target} PROPERTIES POSITION_INDEPENDENT_CODE ON)
    endif()
  endforeach()
  get_property(children DIRECTORY ${directory} PROPERTY SUBDIRECTORIES)
  foreach(child IN LISTS children)
    photorig_static_libraries_position_independent(${child})
  endforeach()
endfunction()
