# Installs the Python package with pip into a fresh virtual environment, as a
# user does (`pip install .`, offline: the system's setuptools and wheel, no
# index), imports it from there without PYTHONPATH, runs the whole Python
# suite against the installed module, and builds a wheel with `python -m
# build` where that is installed. The package build reuses GDR_BUILD_DIR
# (setup.py's GDR_CMAKE_BUILD_DIR), whose module is already built, so this
# costs no compile.
# Run by ctest as: cmake -DSOURCE_DIR=... -DGDR_BUILD_DIR=... -DWORK_DIR=...
#   -DPYTHON=... -DCLI=... -P pip_test.cmake
# Exits with 77 (skipped) where venv, pip or setuptools are missing.
foreach(var SOURCE_DIR GDR_BUILD_DIR WORK_DIR PYTHON)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "pip_test.cmake: ${var} is not set")
  endif()
endforeach()

function(step what)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err WORKING_DIRECTORY "${WORK_DIR}")
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "pip test: ${what} failed (${rc}):\n${out}\n${err}")
  endif()
  message(STATUS "pip test: ${what}: ok\n${out}\n${err}")
endfunction()

function(skip why)
  message(STATUS "pip test: skipped: ${why}")
  # cmake -P has no exit code of its own choosing: ctest reads this line (SKIP_REGULAR_EXPRESSION).
  message("GDR_TEST_SKIPPED: ${why}")
  return()
endfunction()

execute_process(COMMAND "${PYTHON}" -c "import ensurepip, setuptools, wheel" RESULT_VARIABLE rc OUTPUT_QUIET ERROR_QUIET)
if(NOT rc EQUAL 0)
  skip("${PYTHON} lacks ensurepip, setuptools or wheel (Debian: python3-venv, python3-setuptools, python3-wheel)")
  return()
endif()

file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")
set(venv "${WORK_DIR}/venv")
set(py "${venv}/bin/python")
# --system-site-packages: numpy (and matplotlib, tqdm) from the system, as offline there is no index.
step("venv" "${PYTHON}" -m venv --system-site-packages "${venv}")
step("pip install" ${CMAKE_COMMAND} -E env --unset=PYTHONPATH "GDR_CMAKE_BUILD_DIR=${GDR_BUILD_DIR}"
     "${py}" -m pip install --no-build-isolation --no-index --no-cache-dir --disable-pip-version-check "${SOURCE_DIR}")
set(check [=[
import os, sys, gdr
where = os.path.realpath(gdr.__file__)
assert where.startswith(os.path.realpath(sys.prefix)), f"gdr imported from {where}, not from {sys.prefix}"
print("gdr", gdr.__version__, "imported from", where)
]=])
step("import" ${CMAKE_COMMAND} -E env --unset=PYTHONPATH "${py}" -c "${check}")
set(env_args --unset=PYTHONPATH "GDR_SOURCE_DIR=${SOURCE_DIR}" "GDR_TEST_OUT=${WORK_DIR}/test-out" "MPLBACKEND=Agg"
    "PYTHONPYCACHEPREFIX=${WORK_DIR}/pycache")
if(CLI)
  list(APPEND env_args "GDR_CLI=${CLI}")
endif()
file(GLOB tests RELATIVE "${SOURCE_DIR}/tests/python" "${SOURCE_DIR}/tests/python/test_*.py")
list(SORT tests)
# One process per file, as ctest runs them (a file may register reconstructors the others must not see).
foreach(test ${tests})
  execute_process(COMMAND ${CMAKE_COMMAND} -E env ${env_args} "${py}" -m unittest ${test}
                  WORKING_DIRECTORY "${SOURCE_DIR}/tests/python" RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "pip test: ${test} against the installed package failed (${rc}):\n${out}\n${err}")
  endif()
  message(STATUS "pip test: ${test} against the installed package: ok\n${err}")
endforeach()

execute_process(COMMAND "${py}" -c "import build" RESULT_VARIABLE rc OUTPUT_QUIET ERROR_QUIET)
if(rc EQUAL 0)
  step("python -m build" ${CMAKE_COMMAND} -E env --unset=PYTHONPATH "GDR_CMAKE_BUILD_DIR=${GDR_BUILD_DIR}"
       "${py}" -m build --wheel --no-isolation --outdir "${WORK_DIR}/dist" "${SOURCE_DIR}")
  file(GLOB wheels "${WORK_DIR}/dist/gdr-*.whl")
  if(NOT wheels)
    message(FATAL_ERROR "pip test: python -m build made no wheel in ${WORK_DIR}/dist")
  endif()
  message(STATUS "pip test: wheel ${wheels}")
else()
  message(STATUS "pip test: python -m build is not installed (Debian: python3-build): the wheel build is not tried")
endif()
