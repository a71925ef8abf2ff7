// With no OpenCL platform at all (the ICD loader pointed at an empty folder): auto and opencl
// both give the CPU path, say why, and build the same map as the CPU back end.
//
// The loader reads its vendor list once per process, so each check runs in a fresh process
// (a death test in "threadsafe" style re-executes this binary) with OCL_ICD_VENDORS set before
// anything touches OpenCL.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/integrate/cpu_integrator.hpp"
#include "bgkmap/integrate/opencl_integrator.hpp"
#include "bgkmap/mapper.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

// Runs in the child: exits 0 when the back end fell back as it should, 1 (saying why) otherwise.
[[noreturn]] void build_with_hidden_icd(const std::string& backend, const std::filesystem::path& empty_dir) {
  setenv("OCL_ICD_VENDORS", empty_dir.c_str(), 1);
  setenv("OCL_ICD_FILENAMES", "", 1);  // the Khronos loader's variable, in case it is the one installed
  bool ok = true;
  auto fail = [&](const std::string& why) {
    std::fprintf(stderr, "FAILED: %s\n", why.c_str());
    ok = false;
  };
  try {
    list_opencl_devices();
    fail("list_opencl_devices found a platform although the ICD is hidden");
  } catch (const OpenClUnavailable& e) {
    std::fprintf(stderr, "devices: %s\n", e.what());
  }
  BackendOptions options;
  options.backend = backend;
  options.threads = 2;
  std::unique_ptr<Integrator> integrator = make_integrator(options);
  const BackendInfo info = integrator->info();
  std::fprintf(stderr, "backend %s note: %s\n", info.name.c_str(), info.note.c_str());
  if (info.name != "cpu") fail("backend is " + info.name);
  if (info.note.find("no OpenCL platform") == std::string::npos) fail("the note does not say why: " + info.note);

  BuildParams params;
  params.grid.block_depth = 3;
  params.preprocess.max_range_m = 2.5;
  const auto scans = testing::random_scans(3, 3, 200, 2.0f);
  Mapper reference(params, std::make_unique<CpuIntegrator>(2));
  Mapper substitute(params, std::move(integrator));
  for (const Scan& s : scans) {
    reference.insert(s);
    substitute.insert(s);
  }
  const auto& a = reference.map().cell_pool();
  const auto& b = substitute.map().cell_pool();
  if (a.size() != b.size() || a.empty()) fail("different maps");
  for (size_t i = 0; ok && i < a.size(); ++i)
    if (a[i].alpha != b[i].alpha || a[i].beta != b[i].beta) fail("cell " + std::to_string(i) + " differs");
  std::fflush(stderr);
  std::_Exit(ok ? 0 : 1);
}

class OpenClFallback : public ::testing::TestWithParam<const char*> {};

TEST_P(OpenClFallback, NoPlatformMeansTheCpuPathAndTheSameMap) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  const std::filesystem::path empty = testing::make_temp_dir("no-icd");
  EXPECT_EXIT(build_with_hidden_icd(GetParam(), empty), ::testing::ExitedWithCode(0), "backend cpu note: ");
  std::filesystem::remove_all(empty);
}

INSTANTIATE_TEST_SUITE_P(Backends, OpenClFallback, ::testing::Values("auto", "opencl"));

}  // namespace
}  // namespace bgkmap
