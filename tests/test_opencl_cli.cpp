// The OpenCL back end through the bgkmap command: `build --backend opencl` and `--backend cpu`
// give the same map under `query` (within the tolerance of test_opencl_integrator.cpp), the
// report names the device, `devices` lists it, and with no OpenCL platform (the ICD loader
// pointed at an empty folder) both `devices` and `build` say so and the CPU path builds the map.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>

#include "bgkmap/integrate/opencl_integrator.hpp"
#include "bgkmap/io/map_io.hpp"
#include "bgkmap/io/pcd_io.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

constexpr double kRelTol = 1e-5;  // justified in test_opencl_integrator.cpp

using Result = testing::CommandResult;
Result run(const std::string& command) { return testing::run_command(command); }

bool opencl_available(std::string& why) {
  try {
    return !list_opencl_devices().empty();
  } catch (const OpenClUnavailable& e) {
    why = e.what();
    return false;
  }
}

#define BGKMAP_REQUIRE_OPENCL_DEVICE()                                             \
  if (std::string why; !opencl_available(why)) {                                   \
    if (::bgkmap::testing::running_in_ci()) FAIL() << "no OpenCL device: " << why; \
    GTEST_SKIP() << "no OpenCL device: " << why;                                   \
  }

nlohmann::json read_json(const std::filesystem::path& file) {
  std::ifstream in(file);
  return nlohmann::json::parse(in);
}

struct QueryLine {
  double alpha = 0, beta = 0;
  std::string state;
};

std::vector<QueryLine> query(const std::filesystem::path& map, const std::filesystem::path& points) {
  const Result r = run(std::string(BGKMAP_CLI) + " query " + map.string() + " --points " + points.string());
  EXPECT_EQ(r.status, 0) << r.output;
  std::vector<QueryLine> out;
  std::istringstream lines(r.output);
  std::string line;
  while (std::getline(lines, line)) {
    std::istringstream fields(line);
    double cx, cy, cz, mean, variance;
    QueryLine q;
    if (fields >> cx >> cy >> cz >> q.alpha >> q.beta >> mean >> variance >> q.state) out.push_back(q);
  }
  return out;
}

TEST(OpenClCli, DevicesListsTheDevice) {
  BGKMAP_REQUIRE_OPENCL_DEVICE();
  const Result r = run(std::string(BGKMAP_CLI) + " devices");
  EXPECT_EQ(r.status, 0) << r.output;
  const OpenClDeviceInfo first = list_opencl_devices().front();
  EXPECT_NE(r.output.find(first.platform), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(first.name), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("compute units"), std::string::npos) << r.output;
  const Result json = run(std::string(BGKMAP_CLI) + " devices --json");
  EXPECT_EQ(json.status, 0) << json.output;
  const nlohmann::json parsed = nlohmann::json::parse(json.output);
  ASSERT_FALSE(parsed.at("devices").empty());
  EXPECT_GT(parsed["devices"][0].at("compute_units").get<int>(), 0);
}

TEST(OpenClCli, SimStructuredOpenClAndCpuBuildTheSameMap) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  BGKMAP_REQUIRE_OPENCL_DEVICE();
  const auto dir = testing::make_temp_dir("opencl-cli");
  const std::string flags = " -q --ds 0.1 --max-range 8 --resolution 0.1 --ell 0.2 --sigma0 0.1";
  for (const char* backend : {"cpu", "opencl"}) {
    const Result r = run(std::string(BGKMAP_CLI) + " build " + (datasets / "sim_structured").string() + " -o " +
                         (dir / (std::string(backend) + ".bgk")).string() + " --report " +
                         (dir / (std::string(backend) + ".json")).string() + flags + " --backend " + backend);
    ASSERT_EQ(r.status, 0) << r.output;
  }
  const nlohmann::json report = read_json(dir / "opencl.json");
  EXPECT_EQ(report["backend"]["name"], "opencl");
  const std::string device = report["backend"]["device"];
  EXPECT_NE(device.find(list_opencl_devices().front().name), std::string::npos) << device;
  EXPECT_EQ(report["backend"]["note"], "");
  EXPECT_EQ(read_json(dir / "cpu.json")["backend"]["name"], "cpu");
  EXPECT_EQ(report["counts"]["pairs_within_l"], read_json(dir / "cpu.json")["counts"]["pairs_within_l"]);

  // Query points: every cell with evidence in one block of 20 of the CPU map, and random points
  // over the scene (most in unknown space).
  const BgkMap reference = read_native_map(dir / "cpu.bgk");
  std::ofstream points(dir / "points.txt");
  const Grid& grid = reference.grid();
  size_t evidence_points = 0;
  for (uint32_t slot = 0; slot < reference.block_count(); slot += 20)
    for (int i = 0; i < reference.cells_per_block(); ++i) {
      if (!reference.posterior(reference.block_cells(slot)[i]).has_evidence) continue;
      const Vec3d c = grid.cell_center_d(grid.cell_at(reference.key_of_slot(slot), i));
      points << c.x << ' ' << c.y << ' ' << c.z << '\n';
      ++evidence_points;
    }
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> x(-6, 6), y(-5, 5), z(-1, 2.5);
  for (int i = 0; i < 5000; ++i) points << x(rng) << ' ' << y(rng) << ' ' << z(rng) << '\n';
  points.close();
  ASSERT_GT(evidence_points, 1000u);

  const std::vector<QueryLine> cpu = query(dir / "cpu.bgk", dir / "points.txt");
  const std::vector<QueryLine> opencl = query(dir / "opencl.bgk", dir / "points.txt");
  ASSERT_EQ(cpu.size(), evidence_points + 5000);
  ASSERT_EQ(opencl.size(), cpu.size());
  double worst = 0;
  for (size_t i = 0; i < cpu.size(); ++i) {
    worst = std::max({worst, std::abs(cpu[i].alpha - opencl[i].alpha) / cpu[i].alpha,
                      std::abs(cpu[i].beta - opencl[i].beta) / cpu[i].beta});
    EXPECT_EQ(cpu[i].state, opencl[i].state) << "line " << i;
  }
  EXPECT_LE(worst, kRelTol);
  std::printf("  max relative difference %.3g over %zu queries\n", worst, cpu.size());
  std::filesystem::remove_all(dir);
}

// gpom on the device: its leave-one-out samples are solved on the host while the models are
// gathered, in an OpenMP loop, where a kernel matrix that is not positive definite aborted the
// process (status 134); now one line naming --gp-noise, status 1, no map written.
TEST(OpenClCli, GpomWhoseKernelMatrixIsNotPositiveDefiniteEndsInOneLine) {
  BGKMAP_REQUIRE_OPENCL_DEVICE();
  const auto dir = testing::make_temp_dir("opencl-cli-gpom-not-pd");
  const std::string cli = std::string(BGKMAP_CLI) + " ", d = dir.string() + "/";
  const Result sim = run(cli + "simulate structured --sensor planar --scans 3 --drift 0.01,0.002 -q "
                               "--truth-resolution 0 -o " + d + "sim");
  ASSERT_EQ(sim.status, 0) << sim.output;
  for (const char* covariance : {"se", "sparse"}) {
    const Result r = run(cli + "build -q " + d + "sim/scans --max-range 14 --2d --plane-z 1 --threads 2 --method gpom "
                         "--backend opencl --gp-noise 1e-12 --gp-covariance " + covariance + " -o " + d + "m.bt");
    testing::expect_gp_not_positive_definite(r, covariance, d + "m.bt");
  }
  std::filesystem::remove_all(dir);
}

TEST(OpenClCli, AutoTakesAGpuElseTheCpuPathWithoutAWarning) {
  BGKMAP_REQUIRE_OPENCL_DEVICE();
  const auto dir = testing::make_temp_dir("opencl-cli-auto");
  const std::filesystem::path inputs = dir / "scans";
  std::filesystem::create_directories(inputs);
  const auto scans = testing::random_scans(5, 2, 300, 2.0f);
  for (size_t i = 0; i < scans.size(); ++i) write_pcd(inputs / ("scan_" + std::to_string(i) + ".pcd"), scans[i]);
  const Result r = run(std::string(BGKMAP_CLI) + " build -q " + inputs.string() + " -o " + (dir / "auto.bgk").string() +
                       " --report " + (dir / "auto.json").string() + " --max-range 2.5 --block-depth 3");
  ASSERT_EQ(r.status, 0) << r.output;
  const std::vector<OpenClDeviceInfo> devices = list_opencl_devices();
  const bool gpu = std::any_of(devices.begin(), devices.end(), [](const OpenClDeviceInfo& d) { return d.type == "GPU"; });
  const nlohmann::json backend = read_json(dir / "auto.json")["backend"];
  EXPECT_EQ(backend["note"], "");
  EXPECT_EQ(r.output.find("warning"), std::string::npos) << r.output;
  if (gpu) {
    EXPECT_EQ(backend["name"], "opencl");
  } else {
    EXPECT_EQ(backend["name"], "cpu");
    EXPECT_NE(backend["reason"].get<std::string>().find("is not a GPU"), std::string::npos) << backend.dump();
    EXPECT_NE(backend["reason"].get<std::string>().find(devices.front().name), std::string::npos) << backend.dump();
  }
  std::filesystem::remove_all(dir);
}

TEST(OpenClCli, NoPlatformFallsBackWithOneWarningAndTheSameMap) {
  // No device needed: the ICD loader is pointed at an empty folder for the child processes.
  const auto dir = testing::make_temp_dir("opencl-cli-no-icd");
  const std::filesystem::path empty = dir / "no-vendors";
  std::filesystem::create_directories(empty);
  const std::string hide = "OCL_ICD_VENDORS=" + empty.string() + " OCL_ICD_FILENAMES= ";

  const Result devices = run(hide + BGKMAP_CLI + " devices");
  EXPECT_EQ(devices.status, 0) << devices.output;
  EXPECT_NE(devices.output.find("no OpenCL platform"), std::string::npos) << devices.output;

  // Two small random scans, written as PCD.
  const std::filesystem::path inputs = dir / "scans";
  std::filesystem::create_directories(inputs);
  const auto scans = testing::random_scans(4, 2, 300, 2.0f);
  for (size_t i = 0; i < scans.size(); ++i) write_pcd(inputs / ("scan_" + std::to_string(i) + ".pcd"), scans[i]);
  const std::string flags = " --max-range 2.5 --block-depth 3";
  const Result cpu = run(std::string(BGKMAP_CLI) + " build -q " + inputs.string() + " -o " +
                         (dir / "cpu.bgk").string() + flags + " --backend cpu");
  ASSERT_EQ(cpu.status, 0) << cpu.output;
  for (const char* backend : {"opencl", "auto"}) {
    SCOPED_TRACE(backend);
    const Result r = run(hide + BGKMAP_CLI + " build -q " + inputs.string() + " -o " + (dir / "fallback.bgk").string() +
                         " --report " + (dir / "fallback.json").string() + flags + " --backend " + backend);
    ASSERT_EQ(r.status, 0) << r.output;
    // One clear warning, on stderr.
    const size_t warning = r.output.find("warning");
    ASSERT_NE(warning, std::string::npos) << r.output;
    EXPECT_EQ(warning, r.output.rfind("warning")) << r.output;
    EXPECT_NE(r.output.find("no OpenCL platform"), std::string::npos) << r.output;
    const nlohmann::json report = read_json(dir / "fallback.json");
    EXPECT_EQ(report["backend"]["name"], "cpu");
    EXPECT_NE(report["backend"]["note"].get<std::string>().find("no OpenCL platform"), std::string::npos);
    const BgkMap expected = read_native_map(dir / "cpu.bgk");
    const BgkMap actual = read_native_map(dir / "fallback.bgk");
    ASSERT_EQ(expected.cell_pool().size(), actual.cell_pool().size());
    for (size_t i = 0; i < expected.cell_pool().size(); ++i) {
      ASSERT_EQ(expected.cell_pool()[i].alpha, actual.cell_pool()[i].alpha) << i;
      ASSERT_EQ(expected.cell_pool()[i].beta, actual.cell_pool()[i].beta) << i;
    }
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap
