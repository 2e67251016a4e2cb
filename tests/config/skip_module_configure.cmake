# Configures photorig with PHOTORIG_SKIP_MODULES=aravis into BINARY_DIR and
# checks that the build knows the module is missing: the generated
# photorig/config/modules.h says so, and no target needs Aravis.
#   cmake -DSOURCE_DIR=... -DBINARY_DIR=... -DGENERATOR=... -P skip_module_configure.cmake
file(REMOVE_RECURSE "${BINARY_DIR}")
execute_process(
  COMMAND ${CMAKE_COMMAND} -S "${SOURCE_DIR}" -B "${BINARY_DIR}" -G "${GENERATOR}"
          -DPHOTORIG_SKIP_MODULES=aravis -DPHOTORIG_BUILD_BENCH=OFF
  RESULT_VARIABLE status OUTPUT_VARIABLE output ERROR_VARIABLE output)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "configure with PHOTORIG_SKIP_MODULES=aravis failed:\n${output}")
endif()

file(READ "${BINARY_DIR}/rigconfig/include/photorig/config/modules.h" modules)
foreach(expected "PHOTORIG_HAVE_DRIVERS_ARAVIS 0" "PHOTORIG_HAVE_SIM_GIGE 0" "PHOTORIG_HAVE_DRIVERS_V4L2 1")
  string(FIND "${modules}" "#define ${expected}" at)
  if(at EQUAL -1)
    message(FATAL_ERROR "modules.h lacks '#define ${expected}':\n${modules}")
  endif()
endforeach()

# Make lists "... name", Ninja "name: phony".
execute_process(COMMAND ${CMAKE_COMMAND} --build "${BINARY_DIR}" --target help
                RESULT_VARIABLE status OUTPUT_VARIABLE targets ERROR_VARIABLE targets)
foreach(target photorig_capture photorig_service photorig photorigd photorig-sim-modbus test_config)
  string(REGEX MATCH "[ \n]${target}[: \n]" found "${targets}")
  if(NOT found)
    message(FATAL_ERROR "no target ${target} without aravis:\n${targets}")
  endif()
endforeach()
foreach(target photorig_drivers_aravis photorig_sim_gige test_aravis test_gige_end_to_end)
  string(REGEX MATCH "[ \n]${target}[: \n]" found "${targets}")
  if(found)
    message(FATAL_ERROR "target ${target} is still built without aravis")
  endif()
endforeach()
file(REMOVE_RECURSE "${BINARY_DIR}")
