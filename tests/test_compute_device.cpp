// One compute device, chosen once, for every engine: --backend parsed in one place, the same note
// and reason on the integrator, the block Gram engine and the local GP engine, and where each
// runs as a typed kind (a fallback is kCpu, not a string to compare).
#include <gtest/gtest.h>

#include <memory>
#include <stdexcept>
#include <string>

#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/integrate/compute_device.hpp"
#include "bgkmap/integrate/opencl_integrator.hpp"
#include "integrate/block_gram.hpp"
#include "integrate/local_gp_batch.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

// The three engines made from `device` all say what it says.
void expect_engines_follow(const ComputeDevice& device, DeviceKind kind) {
  const BackendInfo infos[] = {make_integrator(device)->info(), make_block_gram(device)->info(),
                               make_local_gp_device(device)->info()};
  for (const BackendInfo& info : infos) {
    EXPECT_EQ(info.kind, kind) << info.note;
    EXPECT_EQ(info.name, device_kind_name(kind));
    EXPECT_EQ(info.note, device.note());
    EXPECT_EQ(info.reason, device.reason());
  }
}

TEST(ComputeDevice, TheBackendNameIsParsedInOnePlace) {
  EXPECT_EQ(parse_backend_request("auto"), BackendRequest::kAuto);
  EXPECT_EQ(parse_backend_request("cpu"), BackendRequest::kCpu);
  EXPECT_EQ(parse_backend_request("opencl"), BackendRequest::kOpenCl);
  for (const char* wrong : {"gpu", "CPU", "", "cuda"}) {
    EXPECT_THROW(parse_backend_request(wrong), std::invalid_argument) << wrong;
    EXPECT_THROW(ComputeDevice::choose(BackendOptions{wrong, "", 1}), std::invalid_argument) << wrong;
  }
  EXPECT_THROW(ComputeDevice::choose(BackendOptions{"cpu", "", -1}), std::invalid_argument);
  EXPECT_STREQ(device_kind_name(DeviceKind::kCpu), "cpu");
  EXPECT_STREQ(device_kind_name(DeviceKind::kOpenCl), "opencl");
}

TEST(ComputeDevice, CpuIsTheCpuWithNothingToSay) {
  const ComputeDevice cpu = ComputeDevice::choose(BackendOptions{"cpu", "any device", 3});
  EXPECT_EQ(cpu.kind(), DeviceKind::kCpu);
  EXPECT_EQ(cpu.requested(), BackendRequest::kCpu);
  EXPECT_EQ(cpu.threads(), 3);
  EXPECT_TRUE(cpu.name().empty());
  EXPECT_TRUE(cpu.note().empty());
  EXPECT_TRUE(cpu.reason().empty());
  expect_engines_follow(cpu, DeviceKind::kCpu);
}

// A device named that is not there: the CPU, one note naming it, the same on every engine.
TEST(ComputeDevice, AMissingDeviceIsTheCpuWithOneNote) {
  for (const char* backend : {"auto", "opencl"}) {
    SCOPED_TRACE(backend);
    const ComputeDevice device = ComputeDevice::choose(BackendOptions{backend, "no such device anywhere", 1});
    EXPECT_EQ(device.kind(), DeviceKind::kCpu);
    EXPECT_NE(device.note().find("no such device anywhere"), std::string::npos) << device.note();
    EXPECT_NE(device.note().find("using the CPU path"), std::string::npos) << device.note();
    EXPECT_TRUE(device.reason().empty());
    expect_engines_follow(device, DeviceKind::kCpu);
  }
}

// The device here (PoCL's CPU device where there is no GPU): opencl runs every engine on it, auto
// takes it only when it is a GPU, and says why not.
TEST(ComputeDevice, TheDeviceHereAndWhatItCan) {
  std::vector<OpenClDeviceInfo> devices;
  try {
    devices = list_opencl_devices();
  } catch (const OpenClUnavailable& e) {
    if (testing::running_in_ci()) FAIL() << e.what();
    GTEST_SKIP() << e.what();
  }
  ASSERT_FALSE(devices.empty());
  const ComputeDevice asked = ComputeDevice::choose(BackendOptions{"opencl", "", 1});
  ASSERT_EQ(asked.kind(), DeviceKind::kOpenCl) << asked.note();
  bool found = false;
  for (const OpenClDeviceInfo& d : devices)
    if (d.full_name() == asked.name()) {
      found = true;
      EXPECT_EQ(asked.capabilities().gpu, d.type == "GPU");
      EXPECT_EQ(asked.capabilities().double_precision, d.double_precision);
    }
  EXPECT_TRUE(found) << asked.name();
  if (asked.capabilities().double_precision) expect_engines_follow(asked, DeviceKind::kOpenCl);
  const ComputeDevice automatic = ComputeDevice::choose(BackendOptions{"auto", "", 1});
  if (asked.capabilities().gpu) {
    EXPECT_EQ(automatic.kind(), DeviceKind::kOpenCl);
  } else {
    EXPECT_EQ(automatic.kind(), DeviceKind::kCpu);
    EXPECT_NE(automatic.reason().find("is not a GPU"), std::string::npos) << automatic.reason();
    EXPECT_NE(automatic.reason().find(asked.name()), std::string::npos) << automatic.reason();
    EXPECT_TRUE(automatic.note().empty()) << automatic.note();
    expect_engines_follow(automatic, DeviceKind::kCpu);
  }
}

// The fallback policy: an engine the device refuses runs on the CPU, noting why.
TEST(ComputeDevice, AnEngineTheDeviceRefusesRunsOnTheCpuSayingWhy) {
  const ComputeDevice cpu = ComputeDevice::choose(BackendOptions{"opencl", "no such device anywhere", 1});
  const ComputeDevice again = cpu.cpu_instead("the kernel did not build");
  EXPECT_EQ(again.kind(), DeviceKind::kCpu);
  EXPECT_EQ(again.note(), "OpenCL unavailable, using the CPU path: the kernel did not build");
}

}  // namespace
}  // namespace bgkmap
