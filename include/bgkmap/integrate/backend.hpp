// Choosing a back end at run time: --backend auto|cpu|opencl, --device, --threads.
#pragma once

#include <memory>
#include <string>

#include "bgkmap/integrate/compute_device.hpp"
#include "bgkmap/integrate/integrator.hpp"

namespace bgkmap {

// Refuses (std::invalid_argument naming --threads) a negative thread count or one beyond
// kMaxThreadsPerCore threads a core (OpenMP's runtime overflows its stack for 100,000 threads).
constexpr int kMaxThreadsPerCore = 8;
void check_thread_count(int threads);

// The integrator on `device`: the OpenCL integrator on an OpenCL device, else the CPU path. When
// the device cannot run it, the CPU path with the reason in BackendInfo::note (the caller prints
// it once); BackendInfo::reason says why auto chose the CPU.
std::unique_ptr<Integrator> make_integrator(const ComputeDevice& device);
// The same on ComputeDevice::choose(options): throws std::invalid_argument for an unknown back end.
std::unique_ptr<Integrator> make_integrator(const BackendOptions& options);

}  // namespace bgkmap
