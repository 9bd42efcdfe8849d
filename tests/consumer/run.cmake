# Installs the gdr build in GDR_BUILD_DIR into a fresh prefix under WORK_DIR,
# then configures, builds and runs the consumer project against it.
# Run by ctest as: cmake -DGDR_BUILD_DIR=... -DWORK_DIR=... -DSOURCE_DIR=...
#   -DSCENE=... -DGENERATOR=... -DCXX=... -DBUILD_TYPE=... -P run.cmake
foreach(var GDR_BUILD_DIR WORK_DIR SOURCE_DIR SCENE GENERATOR CXX)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "run.cmake: ${var} is not set")
  endif()
endforeach()
if(NOT BUILD_TYPE)
  set(BUILD_TYPE Release)
endif()

function(step what)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "consumer test: ${what} failed (${rc}):\n${out}\n${err}")
  endif()
  message(STATUS "consumer test: ${what}: ok")
endfunction()

file(REMOVE_RECURSE "${WORK_DIR}")
step("install" ${CMAKE_COMMAND} --install "${GDR_BUILD_DIR}" --prefix "${WORK_DIR}/prefix")
# The package is the library alone: the tool's and the harness's headers stay in the build tree.
foreach(dir cli eval)
  if(EXISTS "${WORK_DIR}/prefix/include/gdr/${dir}")
    message(FATAL_ERROR "consumer test: the install holds include/gdr/${dir}, which is not part of libgdr")
  endif()
endforeach()
step("configure" ${CMAKE_COMMAND} -S "${SOURCE_DIR}" -B "${WORK_DIR}/build" -G "${GENERATOR}"
     "-DCMAKE_CXX_COMPILER=${CXX}" "-DCMAKE_BUILD_TYPE=${BUILD_TYPE}" "-DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix")
step("build" ${CMAKE_COMMAND} --build "${WORK_DIR}/build")
step("run" "${WORK_DIR}/build/consumer" "${SCENE}")
