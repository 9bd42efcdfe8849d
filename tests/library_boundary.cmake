# libgdr holds the library only: no signal handling or other process-wide
# settings a program must own (those live in the gdr tool, gdr_cli_lib), and
# none of the tool's or the evaluation harness's code.
# Run by ctest as: cmake -DNM=... -DLIBRARY=libgdr.a -P library_boundary.cmake
foreach(var NM LIBRARY)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "library_boundary.cmake: ${var} is not set")
  endif()
endforeach()
execute_process(COMMAND "${NM}" -C "${LIBRARY}" RESULT_VARIABLE rc OUTPUT_VARIABLE symbols ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "library boundary: ${NM} failed on ${LIBRARY} (${rc}):\n${err}")
endif()
string(REPLACE "\n" ";" lines "${symbols}")
set(found "")
foreach(line IN LISTS lines)
  # Calls of process-wide C functions (undefined references), and any
  # definition in the tool's or the harness's namespaces.
  if(line MATCHES " U (signal|sigaction|sigprocmask|pthread_sigmask|raise|setlocale|setenv|putenv|chdir)$"
     OR line MATCHES " [TtWDdBbRrV] gdr::(cli|eval)::")
    list(APPEND found "${line}")
  endif()
endforeach()
if(found)
  list(JOIN found "\n  " text)
  message(FATAL_ERROR "library boundary: ${LIBRARY} holds what belongs to a program:\n  ${text}")
endif()
message(STATUS "library boundary: ${LIBRARY}: no process-wide calls, no CLI or harness code")
