# Installs the gdr build in GDR_BUILD_DIR into a fresh prefix under WORK_DIR,
# then configures, builds and runs a consumer project (SOURCE_DIR) against it,
# with SCENE as its argument where given. EXE names the consumer's
# executable (default: consumer), ARGS a list of arguments to run it with. With FORBID=NAME, the consumer's
# executable must not need a shared library whose name holds NAME (read from
# its dynamic section with READELF): a reconstruction-only consumer does not
# load Embree. With REQUIRE=NAME it must need one (the full consumer does
# load Embree, which shows that the check sees it).
# Run by ctest as: cmake -DGDR_BUILD_DIR=... -DWORK_DIR=... -DSOURCE_DIR=...
#   [-DSCENE=...] [-DFORBID=... | -DREQUIRE=...] [-DREADELF=...] -DGENERATOR=... -DCXX=... -DBUILD_TYPE=... -P run.cmake
foreach(var GDR_BUILD_DIR WORK_DIR SOURCE_DIR GENERATOR CXX)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "run.cmake: ${var} is not set")
  endif()
endforeach()
if(NOT EXE)
  set(EXE consumer)
endif()
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
if(FORBID OR REQUIRE)
  execute_process(COMMAND "${READELF}" -d "${WORK_DIR}/build/${EXE}" RESULT_VARIABLE rc OUTPUT_VARIABLE dyn
                  ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "consumer test: ${READELF} failed (${rc}): ${err}")
  endif()
  string(REGEX MATCHALL "\\(NEEDED\\)[^\n]*" needed "${dyn}")
  if(NOT needed)
    message(FATAL_ERROR "consumer test: ${READELF} -d lists no needed library:\n${dyn}")
  endif()
  list(TRANSFORM needed REPLACE ".*\\[(.*)\\].*" "\\1")
  list(JOIN needed " " text)
  if(FORBID)
    foreach(line IN LISTS needed)
      if(line MATCHES "${FORBID}")
        message(FATAL_ERROR "consumer test: the consumer needs ${line}, which it must not load")
      endif()
    endforeach()
    message(STATUS "consumer test: no ${FORBID} among ${text}")
  else()
    if(NOT text MATCHES "${REQUIRE}")
      message(FATAL_ERROR "consumer test: the consumer needs no ${REQUIRE} library: ${text}")
    endif()
    message(STATUS "consumer test: ${REQUIRE} among ${text}")
  endif()
endif()
if(SCENE)
  step("run" "${WORK_DIR}/build/${EXE}" "${SCENE}")
else()
  step("run" "${WORK_DIR}/build/${EXE}" ${ARGS})
endif()
