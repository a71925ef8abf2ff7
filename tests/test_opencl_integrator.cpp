// The OpenCL back end against the CPU back end (the reference) on the same observations.
//
// Tolerance: alpha and beta agree within 1e-5 relative (kRelTol); pairs within the support are
// equal. Why that holds, and why it is not tighter:
// - Both back ends evaluate the same functions (bgk_math.h: the sparse kernel is polynomial, no
//   libm) in the same order -- per cell, hits then beams in bucket order, each block's sums
//   added to the cell once -- on the same block-local float inputs (LocalHit / LocalBeam, made
//   once on the host), with contraction into fma off on both sides and division and sqrt
//   correctly rounded (-cl-fp32-correctly-rounded-divide-sqrt, which PoCL and the NVIDIA, AMD
//   and Intel drivers support). Within one launch the maps are then bitwise equal; the tests
//   print the largest difference they see, and on PoCL it is 0.
// - A block with more observations than one launch takes is evaluated in parts, each part's
//   sums added to the cell in turn: the same terms, rounded at different points. A float sum of
//   m positive terms is within about sqrt(m) ulp of another order's in practice, (m - 1) ulp at
//   worst; WorkLargerThanOneLaunchIsSplit cuts blocks into parts of a few observations and sees
//   4.7e-6. 1e-5 covers that and hundreds of scans of accumulation on top.
// - Pairs within the support are decided by + - * on equal inputs, so they must match exactly;
//   any observation a back end's culling dropped by mistake would show there.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>

#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/integrate/cpu_integrator.hpp"
#include "bgkmap/integrate/opencl_integrator.hpp"
#include "cli/build_options.hpp"  // with_environment: the command line reads the environment
#include "bgkmap/io/map_io.hpp"
#include "bgkmap/io/pcd_io.hpp"
#include "bgkmap/mapper.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

constexpr double kRelTol = 1e-5;

// The OpenCL integrator, or null with the reason (no device: skipped here, a failure in CI).
std::unique_ptr<Integrator> try_opencl(const OpenClOptions& options, std::string& why) {
  try {
    return make_opencl_integrator(options, 2);
  } catch (const OpenClUnavailable& e) {
    why = e.what();
    return nullptr;
  }
}

#define BGKMAP_REQUIRE_OPENCL(var, options)                                              \
  std::string var##_why;                                                                 \
  std::unique_ptr<Integrator> var = try_opencl(options, var##_why);                      \
  if (!var) {                                                                            \
    if (::bgkmap::testing::running_in_ci()) FAIL() << "no OpenCL device: " << var##_why; \
    GTEST_SKIP() << "no OpenCL device: " << var##_why;                                   \
  }

using testing::small_params;

// Buckets and integrates every scan with `integrator`, as the Mapper does, but from given
// observations (so tests can build observations preprocessing never makes).
BgkMap integrate_all(const BuildParams& params, const std::vector<ScanObservations>& scans, Integrator& integrator,
                     IntegrateStats& stats) {
  BgkMap map(params);
  integrator.host_cells(map, stats, HostAccess::kOverwrite);  // a new map, possibly where the last one lived
  ScanBuckets buckets;
  for (const ScanObservations& obs : scans) {
    bucket_scan(map.grid(), params.kernel.support_radius_m(params.grid.resolution_m), obs, buckets);
    if (params.preprocess.planar) keep_layer_blocks(buckets, map.layer_block_z());
    for (BlockWork& w : buckets.blocks) w.slot = map.ensure_slot(w.key);
    integrator.integrate(obs, buckets, map, stats);
  }
  integrator.host_cells(map, stats);
  return map;
}

// Largest |a - b| / a over alpha and beta of every cell; both maps must have the same slots.
double max_relative_difference(const BgkMap& reference, const BgkMap& other) {
  EXPECT_EQ(reference.block_count(), other.block_count());
  if (reference.block_count() != other.block_count()) return INFINITY;
  double worst = 0;
  for (uint32_t slot = 0; slot < reference.block_count(); ++slot) {
    EXPECT_EQ(reference.key_of_slot(slot), other.key_of_slot(slot)) << "slot " << slot;
    const Cell* a = reference.block_cells(slot);
    const Cell* b = other.block_cells(slot);
    for (int i = 0; i < reference.cells_per_block(); ++i) {
      worst = std::max(worst, std::abs(double(a[i].alpha) - b[i].alpha) / a[i].alpha);
      worst = std::max(worst, std::abs(double(a[i].beta) - b[i].beta) / a[i].beta);
    }
  }
  return worst;
}

size_t cells_with_evidence(const BgkMap& map) { return map.cells_with_evidence(); }

// CPU and OpenCL on the same observations: maps within kRelTol, statistics equal.
void expect_backends_agree(const BuildParams& params, const std::vector<ScanObservations>& scans, Integrator& opencl,
                           double tolerance = kRelTol) {
  CpuIntegrator cpu(2);
  IntegrateStats cpu_stats, ocl_stats;
  const BgkMap expected = integrate_all(params, scans, cpu, cpu_stats);
  const BgkMap actual = integrate_all(params, scans, opencl, ocl_stats);
  const double difference = max_relative_difference(expected, actual);
  EXPECT_LE(difference, tolerance);
  std::printf("  max relative difference %.3g over %zu cells\n", difference, expected.cell_pool().size());
  // Each back end culls pairs its own way (pairs_evaluated differ); the pairs within the support
  // are a property of the observations.
  EXPECT_EQ(cpu_stats.pairs_within_support, ocl_stats.pairs_within_support);
  EXPECT_GT(cpu_stats.pairs_within_support, 0u);
  EXPECT_LE(ocl_stats.pairs_within_support, ocl_stats.pairs_evaluated);
  EXPECT_EQ(cells_with_evidence(expected), cells_with_evidence(actual));
  EXPECT_EQ(opencl.info().name, "opencl") << "fell back: " << opencl.info().note;
}

TEST(OpenClIntegrator, ReportsItsDevice) {
  BGKMAP_REQUIRE_OPENCL(opencl, OpenClOptions{});
  const BackendInfo info = opencl->info();
  EXPECT_EQ(info.name, "opencl");
  EXPECT_NE(info.device.find(" / "), std::string::npos) << info.device;  // "platform / device"
  EXPECT_TRUE(info.note.empty()) << info.note;
  // Bucketing threads: one beside a CPU device (it runs on the same cores), the two asked for
  // beside a GPU (its cores are idle while the device works).
  const bool cpu_device = info.device.find("(CPU,") != std::string::npos;
  EXPECT_EQ(info.threads, cpu_device ? 1 : 2) << info.device;
}

TEST(OpenClIntegrator, ListsDevices) {
  BGKMAP_REQUIRE_OPENCL(opencl, OpenClOptions{});
  const std::vector<OpenClDeviceInfo> devices = list_opencl_devices();
  ASSERT_FALSE(devices.empty());
  bool found = false;
  for (const OpenClDeviceInfo& d : devices) {
    EXPECT_GT(d.compute_units, 0u) << d.full_name();
    EXPECT_GT(d.global_memory_bytes, 0u) << d.full_name();
    EXPECT_EQ(d.version.rfind("OpenCL ", 0), 0u) << d.version;
    found = found || opencl->info().device.rfind(d.full_name(), 0) == 0;
  }
  EXPECT_TRUE(found) << "the integrator's device is not among the listed ones: " << opencl->info().device;
}

TEST(OpenClIntegrator, MatchesCpuOnRandomScenes) {
  BGKMAP_REQUIRE_OPENCL(opencl, OpenClOptions{});
  for (uint32_t seed : {1u, 2u, 3u}) {
    const BuildParams params = small_params();
    expect_backends_agree(params, testing::observations_of(testing::random_scans(seed, 4, 300, 2.0f), params), *opencl);
  }
}

TEST(OpenClIntegrator, MatchesCpuAtEveryBlockDepth) {
  // Depth 1 is one cell per block (work-groups of one); depth 6 has more cells per block than a
  // work-group, so each work-item takes several cells.
  BGKMAP_REQUIRE_OPENCL(opencl, OpenClOptions{});
  for (int depth = 1; depth <= 6; ++depth) {
    SCOPED_TRACE("block depth " + std::to_string(depth));
    const BuildParams params = small_params(depth);
    expect_backends_agree(params, testing::observations_of(testing::random_scans(40 + depth, 2, 200, 2.0f), params), *opencl);
  }
}

TEST(OpenClIntegrator, EveryEightCubeKernelMatchesCpu) {
  // 8^3 blocks with the sparse kernel go to one of three kernels (8, 16 or all 512 cells per
  // work-item; the default picks by device type): each on whatever device there is, against the
  // CPU path. Blocks near the origin hold more beams than one batch of the whole-block kernel.
  const BuildParams params = small_params(4);
  const auto obs = testing::observations_of(testing::random_scans(21, 3, 400, 2.0f), params);
  using Rows = OpenClOptions::RowsPerWorkItem;
  const Rows kinds[] = {Rows::kOneRow, Rows::kTwoRows, Rows::kWholeBlock};
  uint64_t evaluated[3] = {0, 0, 0};
  for (int k = 0; k < 3; ++k) {
    SCOPED_TRACE(k == 0 ? "one row per work-item" : k == 1 ? "two rows per work-item" : "one block per work-item");
    OpenClOptions options;
    options.rows_per_work_item = kinds[k];
    BGKMAP_REQUIRE_OPENCL(opencl, options);
    expect_backends_agree(params, obs, *opencl);
    IntegrateStats stats;
    integrate_all(params, obs, *opencl, stats);
    evaluated[k] = stats.pairs_evaluated;
  }
  // Whole rows or whole row pairs: 8 or 16 pairs per (work-item, observation) evaluated. The
  // whole-block kernel evaluates the row pairs the pairs kernel does.
  EXPECT_EQ(evaluated[0] % 8, 0u);
  EXPECT_EQ(evaluated[1] % 16, 0u);
  EXPECT_NE(evaluated[0], evaluated[1]);
  EXPECT_EQ(evaluated[2], evaluated[1]);
}

// Pose uncertainty through the Mapper, both fusions (the expected sub-map: each sigma point's
// displaced copy integrated into cells set to the prior, the touched blocks copied back for the
// host's moment matching and forth, mapped or packed on the device; the expected kernel: each
// copy with its weight as the kernel's scale): every kernel against the CPU path, 3-D and planar,
// a certain scan before and after the uncertain ones.
TEST(OpenClIntegrator, PoseUncertaintyMatchesCpu) {
  using Rows = OpenClOptions::RowsPerWorkItem;
  using Transfer = OpenClOptions::InputTransfer;
  struct Case {
    int depth;
    Rows rows;
    bool planar;
    Transfer transfer;
  };
  const Case cases[] = {{4, Rows::kOneRow, false, Transfer::kAuto},     {4, Rows::kTwoRows, false, Transfer::kAuto},
                        {4, Rows::kWholeBlock, false, Transfer::kAuto}, {3, Rows::kOneRow, false, Transfer::kAuto},
                        {4, Rows::kWholeBlock, true, Transfer::kAuto},  {4, Rows::kWholeBlock, false, Transfer::kStaged},
                        {4, Rows::kWholeBlock, false, Transfer::kMapped}};
  for (const PoseFusion fusion : {PoseFusion::kExpectedSubmap, PoseFusion::kExpectedKernel})
  for (const Case& c : cases) {
    SCOPED_TRACE(std::string(to_string(fusion)) + ", depth " + std::to_string(c.depth) + (c.planar ? ", planar" : "") +
                 (c.transfer == Transfer::kStaged ? ", staged" : c.transfer == Transfer::kMapped ? ", mapped" : ""));
    OpenClOptions options;
    options.rows_per_work_item = c.rows;
    options.input_transfer = c.transfer;
    BGKMAP_REQUIRE_OPENCL(opencl, options);
    BuildParams params = small_params(c.depth);
    if (c.planar) params.set_planar(0.0);
    params.preprocess.pose_fusion = fusion;
    params.preprocess.pose_sigma = {0.05, 0.03, 0.02, 0.01};
    std::vector<Scan> scans = testing::random_scans(31, 5, 200, 2.0f);
    // A certain scan first (the plain update, maybe still on the device when the next one comes)
    // and last (the device takes the blocks the sub-maps changed on the host).
    scans[0].pose_covariance = PoseCovariance{};
    scans[4].pose_covariance = PoseCovariance{};
    scans[2].pose_covariance = PoseCovariance::from_planar({0.01, 0.002, 0, 0.002, 0.004, 0.0005, 0, 0.0005, 0.001});
    Mapper cpu(params, std::make_unique<CpuIntegrator>(2));
    Mapper ocl(params, std::move(opencl));
    for (const Scan& s : scans) {
      cpu.insert(s);
      ocl.insert(s);
    }
    const double difference = max_relative_difference(cpu.map(), ocl.map());
    EXPECT_LE(difference, kRelTol);
    std::printf("  max relative difference %.3g over %zu cells\n", difference, cpu.map().cell_pool().size());
    EXPECT_EQ(cpu.counts().integrate.pairs_within_support, ocl.counts().integrate.pairs_within_support);
    EXPECT_EQ(ocl.backend().name, "opencl") << "fell back: " << ocl.backend().note;
    EXPECT_GT(cells_with_evidence(cpu.map()), 100u);
  }
}

// A planar map (--2d): every kernel keeps the layer only, and agrees with the CPU path.
TEST(OpenClIntegrator, PlanarMapsMatchCpu) {
  using Rows = OpenClOptions::RowsPerWorkItem;
  struct Case {
    int depth;
    KernelType kernel;
    Rows rows;
    double plane_z;
  };
  const Case cases[] = {{4, KernelType::kSparse, Rows::kOneRow, 0.0},     {4, KernelType::kSparse, Rows::kTwoRows, 0.37},
                        {4, KernelType::kSparse, Rows::kWholeBlock, -0.41}, {3, KernelType::kSparse, Rows::kOneRow, 0.12},
                        {4, KernelType::kBox, Rows::kOneRow, 0.0}};
  for (const Case& c : cases) {
    SCOPED_TRACE("depth " + std::to_string(c.depth) + ", plane " + std::to_string(c.plane_z));
    OpenClOptions options;
    options.rows_per_work_item = c.rows;
    BGKMAP_REQUIRE_OPENCL(opencl, options);
    BuildParams params = small_params(c.depth);
    params.kernel.type = c.kernel;
    params.set_planar(c.plane_z);
    const auto obs = testing::observations_of(testing::random_scans(23, 3, 300, 2.0f), params);
    expect_backends_agree(params, obs, *opencl, c.kernel == KernelType::kBox ? 0.0 : kRelTol);
    IntegrateStats stats;
    const BgkMap map = integrate_all(params, obs, *opencl, stats);
    const int layer = map.layer_local_z(), n = map.grid().cells_per_side();
    size_t layer_evidence = 0;
    for (uint32_t slot = 0; slot < map.block_count(); ++slot) {
      ASSERT_EQ(map.key_of_slot(slot).z, map.layer_block_z());
      const Cell* cells = map.block_cells(slot);
      for (int i = 0; i < map.cells_per_block(); ++i) {
        const bool evidence = cells[i].alpha != params.prior.alpha0 || cells[i].beta != params.prior.beta0;
        if (i / (n * n) != layer) {
          ASSERT_FALSE(evidence) << "cell " << i << " outside the layer";
        }
        layer_evidence += evidence;
      }
    }
    EXPECT_GT(layer_evidence, 100u);
  }
}

TEST(OpenClIntegrator, BoxKernelIsExactlyTheCpuCount) {
  BGKMAP_REQUIRE_OPENCL(opencl, OpenClOptions{});
  BuildParams params = small_params(4);
  params.kernel.type = KernelType::kBox;
  expect_backends_agree(params, testing::observations_of(testing::random_scans(5, 3, 300, 2.0f), params), *opencl, 0.0);
}

TEST(OpenClIntegrator, ZeroLengthBeams) {
  // Beams whose free end is the origin (a point segment), next to ordinary ones, and hits at the
  // origin itself: preprocessing drops such beams, but the integrators must not rely on that.
  BGKMAP_REQUIRE_OPENCL(opencl, OpenClOptions{});
  const BuildParams params = small_params(3);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> coord(-1.0f, 1.0f);
  std::vector<ScanObservations> scans(3);
  for (size_t s = 0; s < scans.size(); ++s) {
    ScanObservations& obs = scans[s];
    obs.origin = {0.05f * s, 0.02f, -0.03f};
    for (int i = 0; i < 50; ++i) obs.free_ends.push_back(obs.origin);
    for (int i = 0; i < 50; ++i) obs.free_ends.push_back({coord(rng), coord(rng), coord(rng)});
    for (int i = 0; i < 20; ++i) obs.hits.push_back(obs.origin);
    for (int i = 0; i < 50; ++i) obs.hits.push_back({coord(rng), coord(rng), coord(rng)});
  }
  expect_backends_agree(params, scans, *opencl);
}

TEST(OpenClIntegrator, VerySmallAndVeryLargeLengthScales) {
  BGKMAP_REQUIRE_OPENCL(opencl, OpenClOptions{});
  for (float ell : {0.02f, 0.06f, 1.5f, 4.0f}) {
    SCOPED_TRACE("ell " + std::to_string(ell));
    BuildParams params = small_params(3);
    params.kernel.ell_m = ell;
    params.kernel.sigma0 = 1.0f;
    // Dense enough that l = 0.02 (a fifth of a cell) still reaches some cell centres.
    expect_backends_agree(params, testing::observations_of(testing::random_scans(11, 2, ell > 1 ? 60 : 3000, 1.0f), params),
                          *opencl);
  }
}

TEST(OpenClIntegrator, HundredsOfScansThroughTheMapper) {
  // The pipelined path: insert() returns while the device works, the map grows every few scans.
  BGKMAP_REQUIRE_OPENCL(opencl, OpenClOptions{});
  const BuildParams params = small_params(3);
  const auto scans = testing::random_scans(77, 300, 60, 3.0f);
  Mapper reference(params, std::make_unique<CpuIntegrator>(2));
  Mapper device(params, std::move(opencl));
  for (const Scan& s : scans) {
    reference.insert(s);
    device.insert(s);
  }
  const double difference = max_relative_difference(reference.map(), device.map());
  EXPECT_LE(difference, kRelTol);
  std::printf("  max relative difference %.3g over %zu cells\n", difference, reference.map().cell_pool().size());
  EXPECT_EQ(reference.counts().integrate.pairs_within_support, device.counts().integrate.pairs_within_support);
  EXPECT_EQ(device.counts().scans, 300u);
  EXPECT_EQ(device.per_scan_insert_s().size(), 300u);
  EXPECT_GT(device.map().block_count(), 64u);  // past the device pool's first size
  // Every launch's kernel time is profiled; the CPU path has none.
  EXPECT_GT(device.counts().integrate.device_kernel_s, 0.0);
  EXPECT_EQ(reference.counts().integrate.device_kernel_s, 0.0);
}

TEST(OpenClIntegrator, ReadingTheMapMidwayChangesNothing) {
  // map() between scans copies the device's cells back; the build then goes on on the device.
  BGKMAP_REQUIRE_OPENCL(opencl, OpenClOptions{});
  const BuildParams params = small_params(3);
  const auto scans = testing::random_scans(8, 6, 200, 2.0f);
  Mapper reference(params, std::make_unique<CpuIntegrator>(2));
  Mapper device(params, std::move(opencl));
  for (const Scan& s : scans) {
    reference.insert(s);
    device.insert(s);
    EXPECT_LE(max_relative_difference(reference.map(), device.map()), kRelTol);
  }
}

TEST(OpenClIntegrator, WorkLargerThanOneLaunchIsSplit) {
  // A few hundred bytes per launch: scans go in many launches and single blocks are cut into
  // several jobs, none dropped.
  const BuildParams params = small_params(3);
  const auto obs = testing::observations_of(testing::random_scans(12, 3, 400, 2.0f), params);
  for (size_t bytes : {size_t(64), size_t(700), size_t(5000)}) {
    SCOPED_TRACE("launch bytes " + std::to_string(bytes));
    OpenClOptions options;
    options.max_launch_bytes = bytes;
    BGKMAP_REQUIRE_OPENCL(opencl, options);
    // Split blocks sum their parts separately: the same numbers, rounded at different points.
    expect_backends_agree(params, obs, *opencl);
  }
}

TEST(OpenClIntegrator, MappedAndStagedInputsGiveTheSameMap) {
  // Both ways of passing launch inputs on whatever device there is (the default picks one by
  // device type): through one launch per scan, many small launches (the inputs' buffers grow and
  // alternate), and a pipelined build of many scans.
  const BuildParams params = small_params(3);
  const auto obs = testing::observations_of(testing::random_scans(14, 3, 400, 2.0f), params);
  const auto scans = testing::random_scans(15, 60, 80, 3.0f);
  for (auto transfer : {OpenClOptions::InputTransfer::kMapped, OpenClOptions::InputTransfer::kStaged}) {
    const bool staged = transfer == OpenClOptions::InputTransfer::kStaged;
    for (size_t bytes : {size_t(0), size_t(700)}) {
      SCOPED_TRACE(std::string(staged ? "staged" : "mapped") + ", launch bytes " + std::to_string(bytes));
      OpenClOptions options;
      options.input_transfer = transfer;
      options.max_launch_bytes = bytes;
      BGKMAP_REQUIRE_OPENCL(opencl, options);
      expect_backends_agree(params, obs, *opencl);
    }
    OpenClOptions options;
    options.input_transfer = transfer;
    BGKMAP_REQUIRE_OPENCL(opencl, options);
    Mapper reference(params, std::make_unique<CpuIntegrator>(2));
    Mapper device(params, std::move(opencl));
    for (const Scan& s : scans) {
      reference.insert(s);
      device.insert(s);
    }
    EXPECT_LE(max_relative_difference(reference.map(), device.map()), kRelTol) << (staged ? "staged" : "mapped");
    EXPECT_EQ(reference.counts().integrate.pairs_within_support, device.counts().integrate.pairs_within_support);
    EXPECT_EQ(device.backend().name, "opencl") << device.backend().note;
  }
}

TEST(OpenClIntegrator, PoolOutOfDeviceMemoryFallsBackToTheCpuPath) {
  // A pool limit of 40 blocks stands in for the device running out of memory mid-build: one
  // warning, the map taken back, the same map from the CPU path; with either way of passing
  // launch inputs (staged ones stay mapped until the integrator goes).
  const BuildParams params = small_params(3);
  const auto scans = testing::random_scans(13, 8, 200, 2.5f);
  for (auto transfer : {OpenClOptions::InputTransfer::kMapped, OpenClOptions::InputTransfer::kStaged}) {
    SCOPED_TRACE(transfer == OpenClOptions::InputTransfer::kStaged ? "staged inputs" : "mapped inputs");
    OpenClOptions options;
    options.max_pool_bytes = 40 * 64 * sizeof(Cell);
    options.input_transfer = transfer;
    BGKMAP_REQUIRE_OPENCL(opencl, options);
    Mapper reference(params, std::make_unique<CpuIntegrator>(2));
    Mapper device(params, std::move(opencl));
    ::testing::internal::CaptureStderr();
    for (const Scan& s : scans) {
      reference.insert(s);
      device.insert(s);
    }
    const std::string warnings = ::testing::internal::GetCapturedStderr();
    EXPECT_LE(max_relative_difference(reference.map(), device.map()), kRelTol);
    EXPECT_EQ(reference.counts().integrate.pairs_within_support, device.counts().integrate.pairs_within_support);
    const BackendInfo info = device.backend();
    EXPECT_EQ(info.name, "cpu");
    EXPECT_NE(info.note.find("device memory"), std::string::npos) << info.note;
    EXPECT_NE(info.note.find("CPU path"), std::string::npos) << info.note;
    // Said once.
    EXPECT_NE(warnings.find("warning"), std::string::npos);
    EXPECT_EQ(warnings.find("warning"), warnings.rfind("warning")) << warnings;
  }
}

TEST(OpenClIntegrator, ResumesANativeMapAndContinuesOnTheDevice) {
  const BuildParams params = small_params(3);
  const auto scans = testing::random_scans(14, 6, 250, 2.0f);
  BGKMAP_REQUIRE_OPENCL(opencl, OpenClOptions{});
  const std::filesystem::path dir = testing::make_temp_dir("opencl-resume");
  const std::filesystem::path file = dir / "half.bgk";
  {
    Mapper first_half(params, std::make_unique<CpuIntegrator>(2));
    for (size_t i = 0; i < 3; ++i) first_half.insert(scans[i]);
    write_native_map(file, first_half.map());
  }
  Mapper reference(params, std::make_unique<CpuIntegrator>(2));
  for (const Scan& s : scans) reference.insert(s);
  Mapper resumed(read_native_map(file), std::move(opencl));
  for (size_t i = 3; i < scans.size(); ++i) resumed.insert(scans[i]);
  EXPECT_EQ(resumed.backend().name, "opencl");
  EXPECT_LE(max_relative_difference(reference.map(), resumed.map()), kRelTol);
  std::filesystem::remove_all(dir);
}

TEST(OpenClIntegrator, DeviceFilterAndEnvironment) {
  BGKMAP_REQUIRE_OPENCL(opencl, OpenClOptions{});
  const std::string device = opencl->info().device;
  // A substring of the chosen device's name picks it, in any case.
  const std::string part = device.substr(device.find(" / ") + 3, 6);
  std::string upper = part;
  for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  BackendOptions options;
  options.backend = "opencl";
  options.device_filter = upper;
  EXPECT_EQ(make_integrator(options)->info().name, "opencl");
  // No such device: the CPU path, saying why.
  options.device_filter = "no-such-device-anywhere";
  auto fallback = make_integrator(options);
  EXPECT_EQ(fallback->info().name, "cpu");
  EXPECT_NE(fallback->info().note.find("no-such-device-anywhere"), std::string::npos) << fallback->info().note;
  // The library reads no environment variable: BGKMAP_OPENCL_DEVICE reaches it only through the
  // command line's (and Python's) with_environment, and only when no --device is given.
  options.device_filter.clear();
  options.backend = "auto";
  setenv("BGKMAP_OPENCL_DEVICE", "no-such-device-anywhere", 1);
  EXPECT_EQ(make_integrator(options)->info().note.find("no-such-device-anywhere"), std::string::npos);
  const BackendOptions from_env = cli::with_environment(options);
  EXPECT_EQ(from_env.device_filter, "no-such-device-anywhere");
  BackendOptions given = options;
  given.device_filter = "given";
  EXPECT_EQ(cli::with_environment(given).device_filter, "given");  // --device wins
  unsetenv("BGKMAP_OPENCL_DEVICE");
  auto fallback_from_env = make_integrator(from_env);
  EXPECT_EQ(fallback_from_env->info().name, "cpu");
  EXPECT_NE(fallback_from_env->info().note.find("no-such-device-anywhere"), std::string::npos)
      << fallback_from_env->info().note;
  options.backend = "opencl";  // auto takes only a GPU (test_opencl_cli)
  EXPECT_EQ(make_integrator(options)->info().name, "opencl");
}

TEST(OpenClIntegrator, BrokenKernelSourceFallsBackWithTheBuildLog) {
  BGKMAP_REQUIRE_OPENCL(opencl, OpenClOptions{});
  const std::filesystem::path dir = testing::make_temp_dir("opencl-broken-kernel");
  std::ofstream(dir / "bgk_block.cl")
      << "__kernel void bgk_block_sparse(__global float* x) { x[0] = undeclared_name; }\n";
  OpenClOptions options;
  options.kernel_dir = dir.string();
  try {
    make_opencl_integrator(options, 1);
    ADD_FAILURE() << "a kernel that does not compile was accepted";
  } catch (const OpenClUnavailable& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("failed to build"), std::string::npos) << what;
    EXPECT_NE(what.find("undeclared_name"), std::string::npos) << "no build log in: " << what;
  }
  // Through make_integrator (BackendOptions::kernel_dir, as BGKMAP_KERNEL_DIR sets it through the
  // command line's with_environment): the CPU path, the same map.
  BackendOptions backend;
  backend.backend = "opencl";
  backend.kernel_dir = dir.string();
  setenv("BGKMAP_KERNEL_DIR", dir.c_str(), 1);
  EXPECT_EQ(cli::with_environment(BackendOptions{}).kernel_dir, dir.string());
  unsetenv("BGKMAP_KERNEL_DIR");
  std::unique_ptr<Integrator> fallback = make_integrator(backend);
  EXPECT_EQ(fallback->info().name, "cpu");
  EXPECT_NE(fallback->info().note.find("undeclared_name"), std::string::npos) << fallback->info().note;
  const BuildParams params = small_params(3);
  const auto scans = testing::random_scans(15, 2, 150, 2.0f);
  Mapper reference(params, std::make_unique<CpuIntegrator>(2));
  Mapper substitute(params, std::move(fallback));
  for (const Scan& s : scans) {
    reference.insert(s);
    substitute.insert(s);
  }
  EXPECT_EQ(reference.map().cell_pool().size(), substitute.map().cell_pool().size());
  EXPECT_EQ(max_relative_difference(reference.map(), substitute.map()), 0.0);
  std::filesystem::remove_all(dir);
}

TEST(OpenClIntegrator, KernelsLoadFromFiles) {
  // BGKMAP_KERNEL_DIR=kernels/ (kernel work without rebuilding; the file includes bgk_math.h) and
  // the self-contained generated file that is installed beside the library give the same map.
  for (const char* dir : {BGKMAP_SOURCE_DIR "/kernels", BGKMAP_GENERATED_KERNEL_DIR}) {
    SCOPED_TRACE(dir);
    OpenClOptions options;
    options.kernel_dir = dir;
    BGKMAP_REQUIRE_OPENCL(opencl, options);
    const BuildParams params = small_params(3);
    expect_backends_agree(params, testing::observations_of(testing::random_scans(16, 2, 200, 2.0f), params), *opencl);
  }
}

TEST(OpenClIntegrator, SimStructuredMatchesCpu) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  BGKMAP_REQUIRE_OPENCL(opencl, OpenClOptions{});
  // The paper's settings (la3dm): 0.1 m cells, l = 0.2 m, sigma0 = 0.1, max range 8 m, 0.1 m
  // downsampling, blocks of 8^3 cells.
  BuildParams params;
  params.preprocess.downsample_m = 0.1;
  params.preprocess.max_range_m = 8;
  std::vector<Scan> scans;
  for (int i = 1; i <= 12; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "scan_%02d.pcd", i);
    scans.push_back(read_pcd(datasets / "sim_structured" / name));
  }
  Mapper reference(params, std::make_unique<CpuIntegrator>(2));
  Mapper device(params, std::move(opencl));
  for (const Scan& s : scans) {
    reference.insert(s);
    device.insert(s);
  }
  EXPECT_GT(reference.map().block_count(), 1000u);
  const double difference = max_relative_difference(reference.map(), device.map());
  EXPECT_LE(difference, kRelTol);
  std::printf("  max relative difference %.3g over %zu cells\n", difference, reference.map().cell_pool().size());
  EXPECT_EQ(reference.counts().integrate.pairs_within_support, device.counts().integrate.pairs_within_support);
  EXPECT_EQ(reference.map().cells_with_evidence(), device.map().cells_with_evidence());
}

}  // namespace
}  // namespace bgkmap
