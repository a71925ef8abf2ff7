#include "opencl_runtime.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <utility>
#include <vector>

namespace bgkmap {
namespace opencl_detail {

// The kernel source with its includes resolved (generated at build time by cmake/EmbedKernel.cmake).
extern const char kBgkBlockSource[];
extern const std::size_t kBgkBlockSource_size;
extern const char kBlockGramSource[];
extern const std::size_t kBlockGramSource_size;
extern const char kLocalGpSource[];
extern const std::size_t kLocalGpSource_size;

std::string cl_error_name(cl_int code) {
  const char* name = "unknown OpenCL error";
  switch (code) {
    case CL_DEVICE_NOT_FOUND: name = "CL_DEVICE_NOT_FOUND"; break;
    case CL_DEVICE_NOT_AVAILABLE: name = "CL_DEVICE_NOT_AVAILABLE"; break;
    case CL_COMPILER_NOT_AVAILABLE: name = "CL_COMPILER_NOT_AVAILABLE"; break;
    case CL_MEM_OBJECT_ALLOCATION_FAILURE: name = "CL_MEM_OBJECT_ALLOCATION_FAILURE"; break;
    case CL_OUT_OF_RESOURCES: name = "CL_OUT_OF_RESOURCES"; break;
    case CL_OUT_OF_HOST_MEMORY: name = "CL_OUT_OF_HOST_MEMORY"; break;
    case CL_BUILD_PROGRAM_FAILURE: name = "CL_BUILD_PROGRAM_FAILURE"; break;
    case CL_MAP_FAILURE: name = "CL_MAP_FAILURE"; break;
    case CL_EXEC_STATUS_ERROR_FOR_EVENTS_IN_WAIT_LIST: name = "CL_EXEC_STATUS_ERROR_FOR_EVENTS_IN_WAIT_LIST"; break;
    case CL_INVALID_VALUE: name = "CL_INVALID_VALUE"; break;
    case CL_INVALID_DEVICE: name = "CL_INVALID_DEVICE"; break;
    case CL_INVALID_BUFFER_SIZE: name = "CL_INVALID_BUFFER_SIZE"; break;
    case CL_INVALID_BUILD_OPTIONS: name = "CL_INVALID_BUILD_OPTIONS"; break;
    case CL_INVALID_KERNEL_NAME: name = "CL_INVALID_KERNEL_NAME"; break;
    case CL_INVALID_KERNEL_ARGS: name = "CL_INVALID_KERNEL_ARGS"; break;
    case CL_INVALID_WORK_GROUP_SIZE: name = "CL_INVALID_WORK_GROUP_SIZE"; break;
    case CL_INVALID_GLOBAL_WORK_SIZE: name = "CL_INVALID_GLOBAL_WORK_SIZE"; break;
    case -1001: name = "CL_PLATFORM_NOT_FOUND_KHR"; break;
    default: break;
  }
  return std::string(name) + " (" + std::to_string(code) + ")";
}

namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

// Drivers pad some strings with NULs and spaces.
std::string trimmed(std::string s) {
  while (!s.empty() && (s.back() == '\0' || std::isspace(static_cast<unsigned char>(s.back())))) s.pop_back();
  return s;
}

std::string device_type_name(cl_device_type type) {
  if (type & CL_DEVICE_TYPE_GPU) return "GPU";
  if (type & CL_DEVICE_TYPE_ACCELERATOR) return "accelerator";
  if (type & CL_DEVICE_TYPE_CPU) return "CPU";
  return "other";
}

struct FoundDevice {
  OpenClDeviceInfo info;
  cl::Device device;
  bool is_gpu = false;
};

OpenClDeviceInfo describe(const cl::Platform& platform, const cl::Device& device) {
  OpenClDeviceInfo d;
  d.platform = trimmed(platform.getInfo<CL_PLATFORM_NAME>());
  d.platform_version = trimmed(platform.getInfo<CL_PLATFORM_VERSION>());
  d.name = trimmed(device.getInfo<CL_DEVICE_NAME>());
  d.type = device_type_name(device.getInfo<CL_DEVICE_TYPE>());
  d.version = trimmed(device.getInfo<CL_DEVICE_VERSION>());
  d.c_version = trimmed(device.getInfo<CL_DEVICE_OPENCL_C_VERSION>());
  d.compute_units = device.getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>();
  d.global_memory_bytes = device.getInfo<CL_DEVICE_GLOBAL_MEM_SIZE>();
  d.max_allocation_bytes = device.getInfo<CL_DEVICE_MAX_MEM_ALLOC_SIZE>();
  d.local_memory_bytes = device.getInfo<CL_DEVICE_LOCAL_MEM_SIZE>();
  d.max_work_group_size = device.getInfo<CL_DEVICE_MAX_WORK_GROUP_SIZE>();
  d.double_precision = device.getInfo<CL_DEVICE_DOUBLE_FP_CONFIG>() != 0;
  return d;
}

std::vector<FoundDevice> find_devices() {
  std::vector<cl::Platform> platforms;
  try {
    cl::Platform::get(&platforms);
  } catch (const cl::Error& e) {
    throw OpenClUnavailable("no OpenCL platform found (" + cl_error_name(e.err()) +
                            "): no OpenCL driver is installed or the ICD loader sees none");
  }
  if (platforms.empty()) throw OpenClUnavailable("no OpenCL platform found: the ICD loader sees no driver");
  std::vector<FoundDevice> found;
  for (const cl::Platform& platform : platforms) {
    std::vector<cl::Device> devices;
    try {
      platform.getDevices(CL_DEVICE_TYPE_ALL, &devices);
    } catch (const cl::Error&) {
      continue;  // CL_DEVICE_NOT_FOUND: a platform without devices
    }
    for (const cl::Device& device : devices) {
      FoundDevice f;
      try {
        f.info = describe(platform, device);
      } catch (const cl::Error&) {
        continue;  // a device that cannot even describe itself is no use
      }
      f.device = device;
      f.is_gpu = f.info.type == "GPU";
      found.push_back(std::move(f));
    }
  }
  return found;
}

// OpenCL C 1.2 or later ("OpenCL C 1.2 PoCL", "OpenCL C 3.0 ...").
bool supports_opencl_c_1_2(const std::string& c_version) {
  int major = 0, minor = 0;
  if (std::sscanf(c_version.c_str(), "OpenCL C %d.%d", &major, &minor) != 2) return false;
  return major > 1 || (major == 1 && minor >= 2);
}

FoundDevice select_device(const std::string& filter) {
  std::vector<FoundDevice> devices = find_devices();
  if (devices.empty()) throw OpenClUnavailable("the OpenCL platforms have no devices");
  std::vector<FoundDevice> usable;
  std::string skipped;
  for (FoundDevice& d : devices) {
    if (!filter.empty() && lower(d.info.full_name()).find(lower(filter)) == std::string::npos) continue;
    if (!supports_opencl_c_1_2(d.info.c_version)) {
      skipped += "; " + d.info.full_name() + " has only " + d.info.c_version;
      continue;
    }
    usable.push_back(std::move(d));
  }
  if (usable.empty()) {
    std::string names;
    for (const FoundDevice& d : devices) names += (names.empty() ? "" : ", ") + ("'" + d.info.full_name() + "'");
    if (!filter.empty())
      throw OpenClUnavailable("no OpenCL device matches '" + filter + "' (devices: " + names + ")" + skipped);
    throw OpenClUnavailable("no OpenCL device supports OpenCL C 1.2 (devices: " + names + ")" + skipped);
  }
  // A GPU when there is one (unless the filter chose), else the first device.
  const auto gpu = std::find_if(usable.begin(), usable.end(), [](const FoundDevice& d) { return d.is_gpu; });
  return std::move(gpu != usable.end() ? *gpu : usable.front());
}

// Each program's embedded text and its file name in a kernel folder.
struct ProgramSource {
  const char* text;
  std::size_t size;
  const char* file;
  bool needs_double;
};
const ProgramSource& program_source(KernelProgram which) {
  static const ProgramSource sources[] = {{kBgkBlockSource, kBgkBlockSource_size, "bgk_block.cl", false},
                                          {kBlockGramSource, kBlockGramSource_size, "block_gram.cl", true},
                                          {kLocalGpSource, kLocalGpSource_size, "local_gp.cl", true}};
  return sources[static_cast<int>(which)];
}

struct KernelSource {
  std::string text;
  std::string origin;         // "embedded" or the file
  std::string include_flags;  // for a file from the source tree, which includes bgk_math.h
};

KernelSource load_kernel_source(const OpenClOptions& options, KernelProgram which) {
  const std::string& dir = options.kernel_dir;
  const ProgramSource& program = program_source(which);
  if (dir.empty()) return {std::string(program.text, program.size), "embedded", ""};
  const std::string file = dir + "/" + program.file;
  std::ifstream in(file, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  if (!in || text.str().empty()) throw OpenClUnavailable("cannot read the OpenCL kernel source " + file);
  // A kernel from the source tree (kernels/) includes "bgkmap/core/bgk_layout.h" from ../include
  // and "core/bgk_math.h" from ../src; the installed and generated copies are self-contained.
  // (Unquoted: not every driver's option parser takes quotes. Such a folder needs no spaces.)
  return {text.str(), file, "-I " + dir + " -I " + dir + "/../include -I " + dir + "/../src"};
}

std::string build_options(const cl::Device& device, const KernelSource& source) {
  std::string flags = "-cl-std=CL1.2 -DBGK_MAX_GROUP=" + std::to_string(kMaxGroupSize);
  // Division and sqrt as the host rounds them, where the device can (OpenCL allows 2.5-3 ulp).
  if (device.getInfo<CL_DEVICE_SINGLE_FP_CONFIG>() & CL_FP_CORRECTLY_ROUNDED_DIVIDE_SQRT)
    flags += " -cl-fp32-correctly-rounded-divide-sqrt";
  if (!source.include_flags.empty()) flags += " " + source.include_flags;
  return flags;
}

std::shared_ptr<const DeviceProgram> build(FoundDevice found, const KernelSource& source) {
  auto result = std::make_shared<DeviceProgram>();
  result->info = found.info;
  result->device = found.device;
  result->source_origin = source.origin;
  const std::string where = "'" + found.info.full_name() + "'";
  try {
    result->context = cl::Context(found.device);
    result->program = cl::Program(result->context, source.text);
  } catch (const cl::Error& e) {
    throw OpenClUnavailable("cannot create an OpenCL context on " + where + ": " + cl_error_name(e.err()));
  }
  const std::string flags = build_options(found.device, source);
  try {
    result->program.build(std::vector<cl::Device>{found.device}, flags.c_str());
  } catch (const cl::Error& e) {
    std::string log;
    try {
      log = trimmed(result->program.getBuildInfo<CL_PROGRAM_BUILD_LOG>(found.device));
    } catch (const cl::Error&) {
      log = "(no build log)";
    }
    throw OpenClUnavailable("the OpenCL kernels (" + source.origin + ") failed to build on " + where + " with " +
                            cl_error_name(e.err()) + "; build log:\n" + log);
  }
  return result;
}

}  // namespace

OpenClDeviceInfo selected_device(const std::string& device_filter) { return select_device(device_filter).info; }

std::shared_ptr<const DeviceProgram> device_program(const OpenClOptions& options, KernelProgram which) {
  FoundDevice found = select_device(options.device_filter);
  if (program_source(which).needs_double && found.device.getInfo<CL_DEVICE_DOUBLE_FP_CONFIG>() == 0)
    throw OpenClUnavailable("'" + found.info.full_name() + "' has no double precision (cl_khr_fp64)");
  const KernelSource source = load_kernel_source(options, which);
  // Built once per process for each device and source: building takes a while (seconds on some
  // drivers) and every integrator on the device can share the program.
  static std::mutex mutex;
  static std::map<std::string, std::shared_ptr<const DeviceProgram>> built;
  const std::string key = found.info.full_name() + "\n" + source.origin + "\n" + source.text;
  std::lock_guard<std::mutex> lock(mutex);
  auto it = built.find(key);
  if (it == built.end()) it = built.emplace(key, build(std::move(found), source)).first;
  return it->second;
}

}  // namespace opencl_detail

std::vector<OpenClDeviceInfo> list_opencl_devices() {
  std::vector<OpenClDeviceInfo> out;
  for (auto& d : opencl_detail::find_devices()) out.push_back(std::move(d.info));
  return out;
}

}  // namespace bgkmap
