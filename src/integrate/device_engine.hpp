// The one way an engine is made from a ComputeDevice: on its OpenCL device when it is one, else
// (or when the device refuses it: a kernel that does not build, first allocations refused) the
// CPU engine, carrying the device's note and reason. Internal to the library.
#pragma once

#include <memory>

#include "bgkmap/integrate/compute_device.hpp"
#include "bgkmap/integrate/opencl_integrator.hpp"

namespace bgkmap {

// on_device(device) -> unique_ptr<Engine> may throw OpenClUnavailable; on_cpu(device) makes the
// CPU engine, its BackendInfo carrying device.note() and device.reason().
template <typename Engine, typename OnDevice, typename OnCpu>
std::unique_ptr<Engine> make_engine(const ComputeDevice& device, OnDevice on_device, OnCpu on_cpu) {
  if (device.kind() == DeviceKind::kOpenCl) {
    try {
      return on_device(device);
    } catch (const OpenClUnavailable& e) {
      return on_cpu(device.cpu_instead(e.what()));
    }
  }
  return on_cpu(device);
}

}  // namespace bgkmap
