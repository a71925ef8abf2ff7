// The OpenCL back end: the map lives on the device, one work-group per touched block evaluates
// every cell against the block's hits and beams (kernels/bgk_block.cl).
//
// The device holds a copy of the map's cell pool, slot for slot (BgkMap keeps the key -> slot
// hash on the host). Per scan only the new observations and the new slots' count go over; the
// cells come back when a HostCells view opens. integrate() returns once the scan's observations
// are copied and its launches queued, so the host can read and bucket the next scan while the
// device works.
//
// Faults never change the map silently: a device that cannot take a scan (memory exhausted,
// launch refused) hands the map back to the host and the rest of the build runs on the CPU path,
// with one warning and the reason in BackendInfo::note. OpenCL itself stays private to the
// library: this header includes no CL header.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "bgkmap/integrate/integrator.hpp"

namespace bgkmap {

// One OpenCL device as `bgkmap devices` lists it.
struct OpenClDeviceInfo {
  std::string platform;          // platform name
  std::string platform_version;  // "OpenCL 3.0 PoCL ..."
  std::string name;              // device name
  std::string type;              // "GPU", "CPU", "accelerator", ...
  std::string version;           // device OpenCL version string
  std::string c_version;         // OpenCL C version string
  uint32_t compute_units = 0;
  uint64_t global_memory_bytes = 0;
  uint64_t max_allocation_bytes = 0;
  uint64_t local_memory_bytes = 0;
  size_t max_work_group_size = 0;
  bool double_precision = false;  // cl_khr_fp64 (CL_DEVICE_DOUBLE_FP_CONFIG not empty)

  // "platform / device": what --device and BGKMAP_OPENCL_DEVICE match against.
  std::string full_name() const { return platform + " / " + name; }
};

// Every device of every platform. Throws OpenClUnavailable when there is no platform at all.
std::vector<OpenClDeviceInfo> list_opencl_devices();

// Why the OpenCL back end cannot run: no platform or device, a kernel build failure (the message
// holds the build log) or a device that refuses the first allocations.
class OpenClUnavailable : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct OpenClOptions {
  // Case-insensitive substring of "platform / device"; empty: the first GPU, else the first device.
  std::string device_filter;
  // Folder to load bgk_block.cl from instead of the source embedded in the library (kernel work and
  // tests; the installed copy is self-contained). Empty: embedded. (The CLI and Python take
  // BGKMAP_KERNEL_DIR into BackendOptions::kernel_dir.)
  std::string kernel_dir;
  // Upper bound on the bytes of observations one launch takes (0: derived from the device's
  // allocation limit). Larger scans, and blocks with more observations, go in several launches.
  size_t max_launch_bytes = 0;
  // Upper bound on the cell pool's device memory (0: the device's allocation limit). Reaching it
  // is treated like an allocation failure (tests use it to exercise the fallback).
  size_t max_pool_bytes = 0;
  // How each launch's observations reach the device. kMapped: the host gathers them straight into
  // the device's buffers, mapped (no copy where the device shares the host's memory). kStaged: into
  // pinned host memory mapped once, then non-blocking copies (mapping device buffers stalls a GPU
  // driver's host side: docs/DESIGN.md, "Back ends"). kAuto: mapped on a CPU device (PoCL), staged
  // on others.
  enum class InputTransfer { kAuto, kMapped, kStaged };
  InputTransfer input_transfer = InputTransfer::kAuto;
  // Cells per work-item in 8^3 blocks with the sparse kernel (kernels/bgk_block.cl). kOneRow: 8
  // (bgk_block_sparse); kTwoRows: 16, in explicit 16-wide vectors (bgk_block_sparse_pairs);
  // kWholeBlock: all 512, one work-item per block running the CPU back end's loops
  // (bgk_block_sparse_whole). kAuto: the whole block on a CPU device (PoCL runs a work-group's
  // work-items one after another, and compiles the vectors to its widest instructions), one row
  // on others (many work-items per block). The same sums either way.
  enum class RowsPerWorkItem { kAuto, kOneRow, kTwoRows, kWholeBlock };
  RowsPerWorkItem rows_per_work_item = RowsPerWorkItem::kAuto;
};

// The OpenCL integrator on the device `options` select, its program built (once per process and
// device). Throws OpenClUnavailable saying why it cannot run.
std::unique_ptr<Integrator> make_opencl_integrator(const OpenClOptions& options, int cpu_fallback_threads);

}  // namespace bgkmap
