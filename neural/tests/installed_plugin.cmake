# The installed gdr finds its installed plugin and model: installs the build
# in GDR_BUILD_DIR into a fresh prefix under WORK_DIR, moves that prefix (the
# lookups are relative to the executable and the plugin, not to the prefix
# the build was configured for), and reconstructs a small gpt render with
# --method neural and no weights given.
# Run by ctest as: cmake -DGDR_BUILD_DIR=... -DWORK_DIR=... -DSCENE=... -P installed_plugin.cmake
foreach(var GDR_BUILD_DIR WORK_DIR SCENE)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "installed_plugin.cmake: ${var} is not set")
  endif()
endforeach()

function(step what)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "installed plugin: ${what} failed (${rc}):\n${out}\n${err}")
  endif()
  set(step_output "${out}${err}" PARENT_SCOPE)
endfunction()

file(REMOVE_RECURSE "${WORK_DIR}")
step("install" ${CMAKE_COMMAND} --install "${GDR_BUILD_DIR}" --prefix "${WORK_DIR}/prefix")
file(RENAME "${WORK_DIR}/prefix" "${WORK_DIR}/moved")
set(gdr "${WORK_DIR}/moved/bin/gdr")
step("render" ${CMAKE_COMMAND} -E env --unset=GDR_PLUGIN_PATH
     "${gdr}" render "${SCENE}" --integrator gpt --spp 2 --set reconstruct=none -o "${WORK_DIR}/gpt.exr")
step("reconstruct" ${CMAKE_COMMAND} -E env --unset=GDR_PLUGIN_PATH
     "${gdr}" reconstruct "${WORK_DIR}/gpt.exr" --method neural -o "${WORK_DIR}/neural.exr")
step("info" "${gdr}" info "${WORK_DIR}/neural.exr")
# The default weights are the installed copy of the shipped model.
string(FIND "${step_output}" "weights=${WORK_DIR}/moved/share/gdr/neural/unet-v4.pt" at)
if(at EQUAL -1)
  message(FATAL_ERROR "installed plugin: the reconstruction did not use the installed model:\n${step_output}")
endif()
message(STATUS "installed plugin: gdr reconstruct --method neural ran from a moved install")
