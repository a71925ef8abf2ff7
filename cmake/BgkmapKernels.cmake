# The OpenCL kernel sources: each kernels/<name>.cl with its includes resolved becomes a
# self-contained file in the build tree (<build>/kernels/, installed beside the library) and a
# C++ byte array compiled into the library (cmake/EmbedKernel.cmake), regenerated whenever the
# kernel or a shared header changes. Sets BGKMAP_KERNEL_SOURCES for the library's sources.
#   bgk_block.cl   BGK-L's block kernels (kBgkBlockSource)
#   block_gram.cl  weighted Gram matrices of sparse rows by block, for bhm (kBlockGramSource)
#   local_gp.cl    batches of local GP models, for gpom and wgpom (kLocalGpSource)

set(BGKMAP_KERNEL_SOURCES "")
foreach(_bgkmap_kernel bgk_block:kBgkBlockSource block_gram:kBlockGramSource local_gp:kLocalGpSource)
  string(REPLACE ":" ";" _bgkmap_kernel "${_bgkmap_kernel}")
  list(GET _bgkmap_kernel 0 _bgkmap_name)
  list(GET _bgkmap_kernel 1 _bgkmap_symbol)
  set(_bgkmap_kernel_in "${PROJECT_SOURCE_DIR}/kernels/${_bgkmap_name}.cl")
  set(_bgkmap_kernel_cl "${PROJECT_BINARY_DIR}/kernels/${_bgkmap_name}.cl")
  set(_bgkmap_kernel_cpp "${PROJECT_BINARY_DIR}/generated/${_bgkmap_name}_cl.cpp")
  add_custom_command(
    OUTPUT "${_bgkmap_kernel_cl}" "${_bgkmap_kernel_cpp}"
    COMMAND "${CMAKE_COMMAND}" -E make_directory "${PROJECT_BINARY_DIR}/kernels" "${PROJECT_BINARY_DIR}/generated"
    COMMAND "${CMAKE_COMMAND}" -DKERNEL=${_bgkmap_kernel_in} -DINCLUDE_DIR=${PROJECT_SOURCE_DIR}/include|${PROJECT_SOURCE_DIR}/src
            -DSYMBOL=${_bgkmap_symbol} -DOUT_CL=${_bgkmap_kernel_cl} -DOUT_CPP=${_bgkmap_kernel_cpp}
            -P "${PROJECT_SOURCE_DIR}/cmake/EmbedKernel.cmake"
    DEPENDS "${_bgkmap_kernel_in}" "${PROJECT_SOURCE_DIR}/src/core/bgk_math.h"
            "${PROJECT_SOURCE_DIR}/src/core/gp_kernel_math.h"
            "${PROJECT_SOURCE_DIR}/include/bgkmap/core/bgk_layout.h"
            "${PROJECT_SOURCE_DIR}/cmake/EmbedKernel.cmake"
    COMMENT "Embedding the OpenCL kernel source ${_bgkmap_name}.cl"
    VERBATIM)
  list(APPEND BGKMAP_KERNEL_SOURCES "${_bgkmap_kernel_cpp}")
  install(FILES "${_bgkmap_kernel_cl}" DESTINATION ${CMAKE_INSTALL_LIBDIR}/bgkmap/kernels)
endforeach()
