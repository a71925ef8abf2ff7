// Choosing a back end at run time: --backend auto|cpu|opencl, --device, --threads.
#pragma once

#include <memory>
#include <string>

#include "bgkmap/integrate/integrator.hpp"

namespace bgkmap {

struct BackendOptions {
  std::string backend = "auto";  // auto: an OpenCL GPU if one works, else the CPU path
  std::string device_filter;     // substring of "platform / device" name; empty: BGKMAP_OPENCL_DEVICE or the first
  int threads = 0;               // host threads (CPU path; bucketing beside a GPU); 0 = all cores
};

// Refuses (std::invalid_argument naming --threads) a negative thread count or one beyond
// kMaxThreadsPerCore threads a core (OpenMP's runtime overflows its stack for 100,000 threads).
constexpr int kMaxThreadsPerCore = 8;
void check_thread_count(int threads);

// The OpenCL device filter the options ask for: --device, else BGKMAP_OPENCL_DEVICE, else empty.
std::string opencl_device_filter(const BackendOptions& options);

// The integrator to use. auto takes the OpenCL device only when it is a GPU, else the CPU path
// (BackendInfo::reason says why). When the requested back end cannot run, falls back to the CPU
// and records why in BackendInfo::note (the caller prints it once). Throws std::invalid_argument
// for an unknown back end name.
std::unique_ptr<Integrator> make_integrator(const BackendOptions& options);

}  // namespace bgkmap
