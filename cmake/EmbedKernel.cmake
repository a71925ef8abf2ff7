# Turns an OpenCL source into one self-contained kernel file and a C++ byte array holding it, so
# that the library works without its kernel files (a moved binary) and the installed copy needs
# no include path. Run as a script at build time:
#   cmake -DKERNEL=<file.cl> -DINCLUDE_DIR=<dir> -DSYMBOL=<C++ name> -DOUT_CL=<file> -DOUT_CPP=<file>
#         -P EmbedKernel.cmake
# Every `#include "path"` is replaced by the text of DIR/path for the first of INCLUDE_DIR's folders holding it (recursively, each file
# once); a quoted include that is not there is an error. <...> includes are left alone (the shared
# header has one in its C++-only branch). The array is not a string literal: those are capped at
# 64 KiB by some compilers.

cmake_minimum_required(VERSION 3.18)

foreach(var KERNEL INCLUDE_DIR SYMBOL OUT_CL OUT_CPP)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "EmbedKernel.cmake: ${var} is not set")
  endif()
endforeach()

# INCLUDE_DIR: the folders searched in order, separated by '|' (a ';' would split the argument).
string(REPLACE "|" ";" include_dirs "${INCLUDE_DIR}")
file(READ "${KERNEL}" source)
set(embedded "")
while(TRUE)
  string(REGEX MATCH "#[ \t]*include[ \t]*\"[^\"\n]+\"" directive "${source}")
  if(NOT directive)
    break()
  endif()
  string(REGEX REPLACE "^#[ \t]*include[ \t]*\"([^\"]+)\"$" "\\1" name "${directive}")
  set(path "")
  foreach(dir IN LISTS include_dirs)
    if(NOT path AND EXISTS "${dir}/${name}")
      set(path "${dir}/${name}")
    endif()
  endforeach()
  if(NOT path)
    message(FATAL_ERROR "${KERNEL}: cannot embed #include \"${name}\": not found under ${INCLUDE_DIR}")
  endif()
  set(text "")
  if(NOT name IN_LIST embedded)
    list(APPEND embedded "${name}")
    file(READ "${path}" text)
    set(text "/* ---- begin ${name} ---- */\n${text}/* ---- end ${name} ---- */")
  endif()
  string(FIND "${source}" "${directive}" at)
  string(LENGTH "${directive}" directive_length)
  string(SUBSTRING "${source}" 0 ${at} before)
  math(EXPR after_at "${at} + ${directive_length}")
  string(SUBSTRING "${source}" ${after_at} -1 after)
  set(source "${before}${text}${after}")
endwhile()

get_filename_component(kernel_name "${KERNEL}" NAME)
set(source "/* Generated from kernels/${kernel_name} by cmake/EmbedKernel.cmake (includes resolved); do not edit. */\n${source}")
file(WRITE "${OUT_CL}.tmp" "${source}")

file(READ "${OUT_CL}.tmp" hex HEX)
string(LENGTH "${hex}" hex_length)
math(EXPR size "${hex_length} / 2")
string(REGEX REPLACE "([0-9a-f][0-9a-f])" "0x\\1," bytes "${hex}")
string(REPEAT "0x[0-9a-f][0-9a-f]," 16 sixteen_bytes)
string(REGEX REPLACE "(${sixteen_bytes})"
       "\\1\n  " bytes "${bytes}")
file(WRITE "${OUT_CPP}.tmp"
"// Generated from kernels/${kernel_name} by cmake/EmbedKernel.cmake; do not edit.
#include <cstddef>

namespace bgkmap::opencl_detail {
extern const char ${SYMBOL}[];
extern const std::size_t ${SYMBOL}_size;
// The kernel source, NUL-terminated; ${SYMBOL}_size excludes the NUL.
const char ${SYMBOL}[] = {
  ${bytes}0x00};
const std::size_t ${SYMBOL}_size = ${size};
}  // namespace bgkmap::opencl_detail
")
# Replace only on change so that an unchanged kernel does not recompile anything.
execute_process(COMMAND ${CMAKE_COMMAND} -E copy_if_different "${OUT_CL}.tmp" "${OUT_CL}")
execute_process(COMMAND ${CMAKE_COMMAND} -E copy_if_different "${OUT_CPP}.tmp" "${OUT_CPP}")
file(REMOVE "${OUT_CL}.tmp" "${OUT_CPP}.tmp")
