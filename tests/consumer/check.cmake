# The out-of-tree consumer test: installs the build tree to a fresh prefix, configures and builds
# tests/consumer against it with find_package(bgkmap COMPONENTS core), runs it, and checks that
# the program needs the core library only (none of the other bgkmap libraries, nor OctoMap, cairo or yaml-cpp).
#   cmake -DBUILD_DIR=<build> -DSOURCE_DIR=<tests/consumer> -DWORK_DIR=<scratch> [-DCXX_COMPILER=<c++>
#         -DSANITIZE=<address,undefined>] -P check.cmake
foreach(var BUILD_DIR SOURCE_DIR WORK_DIR)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "check.cmake: ${var} is not set")
  endif()
endforeach()
file(REMOVE_RECURSE "${WORK_DIR}")
set(prefix "${WORK_DIR}/prefix")

function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "failed (${rc}): ${ARGN}\n${out}\n${err}")
  endif()
  set(run_output "${out}" PARENT_SCOPE)
endfunction()

run("${CMAKE_COMMAND}" --install "${BUILD_DIR}" --prefix "${prefix}")
# An instrumented library (scripts/sanitize.sh) needs its consumer built by the same compiler with
# the same sanitizers, whose runtimes the program then carries.
set(instrumented)
if(SANITIZE)
  set(instrumented "-DCMAKE_CXX_COMPILER=${CXX_COMPILER}" "-DCMAKE_CXX_FLAGS=-fsanitize=${SANITIZE}"
                   "-DCMAKE_EXE_LINKER_FLAGS=-fsanitize=${SANITIZE}")
endif()
run("${CMAKE_COMMAND}" -S "${SOURCE_DIR}" -B "${WORK_DIR}/build" "-DCMAKE_PREFIX_PATH=${prefix}"
    -DCMAKE_BUILD_TYPE=Release ${instrumented})
run("${CMAKE_COMMAND}" --build "${WORK_DIR}/build")
find_program(readelf readelf REQUIRED)
run("${readelf}" -d "${WORK_DIR}/build/consumer")
string(REGEX MATCHALL "\\[[^]]+\\]" needed "${run_output}")
message(STATUS "consumer needs: ${needed}")
if(NOT needed MATCHES "libbgkmap_core")
  message(FATAL_ERROR "the consumer does not link the core library: ${needed}")
endif()
if(needed MATCHES "libbgkmap_(io|methods|sim|eval)|octomap|cairo|yaml")
  message(FATAL_ERROR "the consumer of bgkmap::core links more than the core: ${needed}")
endif()
run("${readelf}" -d "${prefix}/lib/libbgkmap_core.so")
if(run_output MATCHES "octomap|cairo|yaml|libbgkmap_(io|methods|sim|eval)")
  message(FATAL_ERROR "the core library needs an extra:\n${run_output}")
endif()
set(ENV{LD_LIBRARY_PATH} "${prefix}/lib")
run("${WORK_DIR}/build/consumer" "${WORK_DIR}/map.bgk")
message(STATUS "${run_output}")
