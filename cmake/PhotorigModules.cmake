# Adds every immediate subdirectory of the current source directory that has a
# CMakeLists.txt, in name order. New modules (a driver, a solver, a test area)
# join the build by existing; no parent list needs editing.
function(photorig_add_module_subdirectories)
  file(GLOB children LIST_DIRECTORIES true CONFIGURE_DEPENDS "${CMAKE_CURRENT_SOURCE_DIR}/*")
  list(SORT children)
  foreach(child IN LISTS children)
    if(IS_DIRECTORY "${child}" AND EXISTS "${child}/CMakeLists.txt")
      add_subdirectory("${child}")
    endif()
  endforeach()
endfunction()
