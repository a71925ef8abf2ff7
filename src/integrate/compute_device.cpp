#include "bgkmap/integrate/compute_device.hpp"

#include <stdexcept>

#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/integrate/opencl_integrator.hpp"
#include "integrate/opencl/opencl_runtime.hpp"

namespace bgkmap {

const char* device_kind_name(DeviceKind kind) { return kind == DeviceKind::kOpenCl ? "opencl" : "cpu"; }

BackendRequest parse_backend_request(const std::string& name) {
  if (name == "auto") return BackendRequest::kAuto;
  if (name == "cpu") return BackendRequest::kCpu;
  if (name == "opencl") return BackendRequest::kOpenCl;
  throw std::invalid_argument("unknown backend '" + name + "' (expected auto, cpu or opencl)");
}

ComputeDevice ComputeDevice::cpu(int threads) {
  check_thread_count(threads);
  ComputeDevice d;
  d.threads_ = threads;
  return d;
}

ComputeDevice ComputeDevice::choose(const BackendOptions& options) {
  ComputeDevice d = cpu(options.threads);
  d.requested_ = parse_backend_request(options.backend);
  if (d.requested_ == BackendRequest::kCpu) return d;
  d.device_filter_ = options.device_filter;
  d.kernel_dir_ = options.kernel_dir;
  OpenClDeviceInfo info;
  try {
    info = opencl_detail::selected_device(d.device_filter_);
  } catch (const OpenClUnavailable& e) {
    return d.cpu_instead(e.what());
  }
  d.capabilities_ = {info.type == "GPU", info.double_precision};
  if (d.requested_ == BackendRequest::kAuto && !d.capabilities_.gpu) {
    // On the same CPU the OpenMP path beats an OpenCL CPU driver (PoCL): auto takes only a GPU.
    d.reason_ = "the OpenCL device '" + info.full_name() +
                "' is not a GPU, and the CPU path is faster on the same CPU (--backend opencl uses it)";
    return d;
  }
  d.kind_ = DeviceKind::kOpenCl;
  d.name_ = info.full_name();
  return d;
}

ComputeDevice ComputeDevice::cpu_instead(const std::string& why) const {
  ComputeDevice d = *this;
  d.kind_ = DeviceKind::kCpu;
  d.name_.clear();
  d.note_ = std::string(requested_ == BackendRequest::kAuto ? "no usable OpenCL device" : "OpenCL unavailable") +
            ", using the CPU path: " + why;
  return d;
}

ComputeDevice ComputeDevice::for_double_precision() const {
  if (kind_ != DeviceKind::kOpenCl || capabilities_.double_precision || requested_ != BackendRequest::kAuto)
    return *this;
  ComputeDevice d = *this;
  d.kind_ = DeviceKind::kCpu;
  d.reason_ = "the OpenCL GPU '" + name_ + "' has no double precision (cl_khr_fp64), which this method's kernels need";
  d.name_.clear();
  return d;
}

}  // namespace bgkmap
