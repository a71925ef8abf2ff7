// bgkmap devices: the OpenCL platforms and devices this machine offers, as --device sees them.
#include <cstdio>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bgkmap/integrate/opencl_integrator.hpp"
#include "cli/commands.hpp"

namespace bgkmap::cli {

namespace {

std::string mib(uint64_t bytes) { return std::to_string(bytes >> 20) + " MiB"; }

nlohmann::json to_json(const OpenClDeviceInfo& d) {
  return {{"platform", d.platform},
          {"platform_version", d.platform_version},
          {"device", d.name},
          {"type", d.type},
          {"version", d.version},
          {"c_version", d.c_version},
          {"compute_units", d.compute_units},
          {"global_memory_bytes", d.global_memory_bytes},
          {"max_allocation_bytes", d.max_allocation_bytes},
          {"local_memory_bytes", d.local_memory_bytes},
          {"max_work_group_size", d.max_work_group_size}};
}

void run_devices(bool json) {
  std::vector<OpenClDeviceInfo> devices;
  try {
    devices = list_opencl_devices();
  } catch (const OpenClUnavailable& e) {
    // Not an error of this command: it answers the question, and builds use the CPU path.
    if (json)
      std::printf("%s\n", nlohmann::json{{"platforms", nlohmann::json::array()}, {"note", e.what()}}.dump(2).c_str());
    else
      std::printf("%s\nBuilds will use the CPU path.\n", e.what());
    return;
  }
  if (json) {
    nlohmann::json out = nlohmann::json::array();
    for (const OpenClDeviceInfo& d : devices) out.push_back(to_json(d));
    std::printf("%s\n", nlohmann::json{{"devices", out}}.dump(2).c_str());
    return;
  }
  // Grouped by platform, in the order the ICD loader gives them.
  std::string platform;
  for (const OpenClDeviceInfo& d : devices) {
    if (d.platform != platform) {
      platform = d.platform;
      std::printf("%s (%s)\n", d.platform.c_str(), d.platform_version.c_str());
    }
    std::printf("  %s [%s]: %u compute units, %s memory (%s per buffer), %s local, %s, %s\n", d.name.c_str(),
                d.type.c_str(), d.compute_units, mib(d.global_memory_bytes).c_str(),
                mib(d.max_allocation_bytes).c_str(), (std::to_string(d.local_memory_bytes >> 10) + " KiB").c_str(),
                d.version.c_str(), d.c_version.c_str());
  }
  if (devices.empty())
    std::printf("OpenCL platforms found, but no devices.\n");
  else
    std::printf(
        "Choose one with --device SUBSTRING or BGKMAP_OPENCL_DEVICE (matched against \"platform / device\").\n");
}

}  // namespace

void add_devices_command(CLI::App& app) {
  auto json = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand("devices", "List OpenCL platforms and devices (compute units, memory, version)");
  cmd->add_flag("--json", *json, "Print JSON instead of text");
  cmd->callback([json] { run_devices(*json); });
}

}  // namespace bgkmap::cli
