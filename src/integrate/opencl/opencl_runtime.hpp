// Private to the OpenCL back end: the Khronos C++ bindings, device discovery and the built program.
// Only src/integrate/opencl/*.cpp include this header (and with it CL/opencl.hpp).
#pragma once

#define CL_HPP_TARGET_OPENCL_VERSION 120
#define CL_HPP_MINIMUM_OPENCL_VERSION 120
#define CL_HPP_ENABLE_EXCEPTIONS
#include <CL/opencl.hpp>

#include <algorithm>
#include <memory>
#include <string>

#include "bgkmap/integrate/opencl_integrator.hpp"

namespace bgkmap::opencl_detail {

// The largest work-group the block kernels are launched with; the kernels size their local
// reduction scratch by it (-DBGK_MAX_GROUP).
inline constexpr size_t kMaxGroupSize = 256;
// The smallest: blocks of fewer cells (depth 1 to 3) leave work-items idle rather than launch
// work-groups of one or two, which PoCL's kernel compiler handles by a different method that
// fails on the kernels' barriers in loops.
inline constexpr size_t kMinGroupSize = 16;
// Cells one work-item evaluates: a run along x (kernels/bgk_block.cl: BGK_RUN).
inline constexpr int kCellsPerWorkItem = 8;

// The kernel sources: kernels/bgk_block.cl (BGK-L's block kernels), kernels/block_gram.cl
// (weighted Gram matrices of sparse rows by block, for the Bayesian Hilbert map) and
// kernels/local_gp.cl (batches of gpom's local GP models); the last two in double precision.
enum class KernelProgram { kBgkBlock, kBlockGram, kLocalGp };

// A device with one kernel source built for it. Shared (read-only) by every integrator on that
// device; each integrator makes its own queues and cl::Kernel objects.
struct DeviceProgram {
  OpenClDeviceInfo info;
  cl::Device device;
  cl::Context context;
  cl::Program program;
  std::string source_origin;  // "embedded" or the file the kernels came from
};

// The device `options` select with the program `which` built: once per process for each device
// and kernel source (later calls get the same object). Throws OpenClUnavailable saying why not
// (for the double-precision programs also when the device has no cl_khr_fp64).
std::shared_ptr<const DeviceProgram> device_program(const OpenClOptions& options,
                                                    KernelProgram which = KernelProgram::kBgkBlock);

// The device device_program picks for this filter (a GPU when there is one, else the first), not
// built. Throws OpenClUnavailable when there is none.
OpenClDeviceInfo selected_device(const std::string& device_filter);

// A device buffer that grows by doubling (a growing batch does not reallocate every time), for
// the engines that stage host arrays (block_gram_opencl, local_gp_opencl).
struct GrowingBuffer {
  cl::Buffer buffer;
  size_t bytes = 0;

  void reserve(const cl::Context& context, size_t at_least) {
    at_least = std::max<size_t>(at_least, 8);
    if (at_least <= bytes) return;
    bytes = std::max(at_least, 2 * bytes);
    buffer = cl::Buffer(context, CL_MEM_READ_WRITE, bytes);
  }
  // Grown to hold `count` values and their copy queued (not waited for).
  template <typename T>
  void upload(const cl::Context& context, cl::CommandQueue& queue, const T* data, size_t count) {
    reserve(context, count * sizeof(T));
    if (count > 0) queue.enqueueWriteBuffer(buffer, CL_FALSE, 0, count * sizeof(T), data);
  }
};

// "CL_OUT_OF_RESOURCES (-5)" for an OpenCL error code.
std::string cl_error_name(cl_int code);

}  // namespace bgkmap::opencl_detail
