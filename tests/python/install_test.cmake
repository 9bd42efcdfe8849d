# Installs the gdr build in GDR_BUILD_DIR into a fresh prefix under WORK_DIR,
# as a user does (cmake --install), then imports the installed module from
# outside the build tree and renders with it.
# Run by ctest as: cmake -DGDR_BUILD_DIR=... -DWORK_DIR=... -DPYTHON=...
#   -DMODULE_DIR=lib/pythonX.Y/dist-packages -DSCENE=... -P install_test.cmake
foreach(var GDR_BUILD_DIR WORK_DIR PYTHON MODULE_DIR SCENE)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "install_test.cmake: ${var} is not set")
  endif()
endforeach()

function(step what)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err WORKING_DIRECTORY "${WORK_DIR}")
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "python install test: ${what} failed (${rc}):\n${out}\n${err}")
  endif()
  message(STATUS "python install test: ${what}: ok\n${out}")
endfunction()

file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")
step("install" ${CMAKE_COMMAND} --install "${GDR_BUILD_DIR}" --prefix "${WORK_DIR}/prefix")
set(site "${WORK_DIR}/prefix/${MODULE_DIR}")
file(GLOB modules "${site}/gdr*.so")
if(NOT modules)
  message(FATAL_ERROR "python install test: no gdr module in ${site}")
endif()
# Only the prefix on the path: the module must come from there, not from the build tree.
# (The emitter-wall scene's every pixel is its emitter's radiance, (3, 2, 0.5).)
set(check [=[
import os, sys, gdr
where = os.path.realpath(gdr.__file__)
assert where.startswith(os.path.realpath(sys.argv[1])), where
img = gdr.render(gdr.load_scene(sys.argv[2]), integrator="pt", spp=2)
assert img["color"].shape == (8, 10, 3), img["color"].shape
assert (img["color"] == [3.0, 2.0, 0.5]).all(), img["color"][0, 0]
print("imported", where, "and rendered", img.stats)
]=])
step("import" ${CMAKE_COMMAND} -E env --unset=PYTHONPATH "PYTHONPATH=${site}" "${PYTHON}" -c "${check}" "${site}" "${SCENE}")
