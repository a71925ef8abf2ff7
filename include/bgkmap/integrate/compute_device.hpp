// The compute device a build's engines run on, chosen once from --backend, --device and --threads:
// the CPU or one OpenCL device, what it can do, and why it was chosen. The engines (the
// integrator, bhm's block Gram engine, gpom's local GP device) are made from it and share one
// fallback policy: an engine that cannot run on the device runs on the CPU, the same map, and its
// BackendInfo::note says why (the caller prints it once).
#pragma once

#include <string>

namespace bgkmap {

struct BackendOptions {
  std::string backend = "auto";  // auto: an OpenCL GPU if one works, else the CPU path
  std::string device_filter;     // substring of "platform / device" name; empty: the first GPU, else the first device
  int threads = 0;               // host threads (CPU path; bucketing beside a GPU); 0 = all cores
  std::string kernel_dir;        // the OpenCL kernels' sources from this folder; empty: the embedded ones
};

// Where an engine's work runs: the typed form of BackendInfo::name ("cpu", "opencl").
enum class DeviceKind { kCpu, kOpenCl };
const char* device_kind_name(DeviceKind kind);

// What --backend asks for.
enum class BackendRequest { kAuto, kCpu, kOpenCl };
// The one parser of --backend's value; throws std::invalid_argument for anything but auto, cpu, opencl.
BackendRequest parse_backend_request(const std::string& name);

struct DeviceCapabilities {
  bool gpu = false;               // a GPU (else a CPU driver such as PoCL, or another accelerator)
  bool double_precision = false;  // cl_khr_fp64: the block Gram and local GP kernels need it
};

class ComputeDevice {
 public:
  // cpu: the CPU. opencl: the device the options select. auto: that device only when it is a GPU
  // (on the same CPU the OpenMP path beats a CPU driver such as PoCL: reason() says so). Without a
  // usable device, the CPU with note() saying why. Throws std::invalid_argument for an unknown
  // back end or thread count. Lists the devices; builds no kernel.
  static ComputeDevice choose(const BackendOptions& options);
  static ComputeDevice cpu(int threads);

  DeviceKind kind() const { return kind_; }
  BackendRequest requested() const { return requested_; }
  const DeviceCapabilities& capabilities() const { return capabilities_; }
  const std::string& name() const { return name_; }  // "platform / device" on OpenCL, else empty
  const std::string& device_filter() const { return device_filter_; }  // BackendOptions::device_filter
  const std::string& kernel_dir() const { return kernel_dir_; }        // BackendOptions::kernel_dir
  int threads() const { return threads_; }  // host threads; 0: all cores
  const std::string& reason() const { return reason_; }  // why auto took the CPU (no warning), else empty
  const std::string& note() const { return note_; }  // why the CPU runs in place of what was asked (a warning)

  // The fallback policy, for an engine that cannot run on this device (`why`: what refused it):
  // the CPU, with a note saying why when the device was asked for or is a GPU auto chose.
  ComputeDevice cpu_instead(const std::string& why) const;
  // This device for an engine that computes in double precision: under auto, the CPU (with a
  // reason) on a device without it; otherwise unchanged (asked for, the engine's build says why not).
  ComputeDevice for_double_precision() const;

 private:
  DeviceKind kind_ = DeviceKind::kCpu;
  BackendRequest requested_ = BackendRequest::kCpu;
  DeviceCapabilities capabilities_;
  std::string name_, device_filter_, kernel_dir_, reason_, note_;
  int threads_ = 0;
};

}  // namespace bgkmap
