#include "support/test_support.hpp"

#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "datasets/locate.hpp"

#include <cmath>
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <random>

namespace bgkmap::testing {

std::filesystem::path datasets_dir() { return datasets::datasets_dir(BGKMAP_DEFAULT_DATASETS_DIR); }

bool running_in_ci() {
  const char* ci = std::getenv("CI");
  return ci && std::string(ci) == "true";
}

BackendOptions cpu_backend(int threads) {
  BackendOptions backend;
  backend.backend = "cpu";
  backend.threads = threads;
  return backend;
}

std::filesystem::path make_temp_dir(const std::string& tag) {
  static std::mt19937_64 rng(std::random_device{}());
  for (;;) {
    const auto dir = std::filesystem::temp_directory_path() / ("bgkmap-" + tag + "-" + std::to_string(rng() % 1000000000));
    if (std::filesystem::create_directories(dir)) return dir;
  }
}

std::string read_bytes(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void write_bytes(const std::filesystem::path& file, const std::string& bytes) {
  std::error_code ec;
  std::filesystem::remove(file, ec);
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  ASSERT_TRUE(out.good()) << file;
}

std::vector<Scan> read_all_scans(const std::vector<std::filesystem::path>& inputs) {
  ScanSource source(inputs);
  std::vector<Scan> scans;
  Scan scan;
  while (source.next(scan)) scans.push_back(scan);
  return scans;
}

void expect_same_cells(const BgkMap& expected, const BgkMap& actual) {
  ASSERT_EQ(expected.block_count(), actual.block_count());
  const size_t cells = static_cast<size_t>(expected.cells_per_block());
  for (uint32_t slot = 0; slot < expected.block_count(); ++slot) {
    const BlockKey& key = expected.key_of_slot(slot);
    ASSERT_EQ(actual.key_of_slot(slot), key) << "slot " << slot;
    ASSERT_EQ(actual.find_slot(key), static_cast<int64_t>(slot));
    ASSERT_EQ(std::memcmp(expected.block_cells(slot), actual.block_cells(slot), cells * sizeof(Cell)), 0)
        << "block (" << key.x << ", " << key.y << ", " << key.z << ")";
  }
}

void expect_input_error(const std::filesystem::path& file, const std::function<void()>& action,
                        const std::string& context) {
  try {
    action();
    ADD_FAILURE() << context << ": no error for " << file;
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_EQ(e.file(), file) << context;
    EXPECT_EQ(message.rfind(file.string() + ": ", 0), 0u) << context << ": " << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << context << ": " << message;
    EXPECT_EQ(message.find("out of memory"), std::string::npos) << context << ": " << message;
  } catch (const std::exception& e) {
    ADD_FAILURE() << context << ": " << file << " threw a non-InputError: " << e.what();
  }
}

std::vector<Scan> random_scans(uint32_t seed, int scans, int points_per_scan, float extent_m) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> coord(-extent_m, extent_m);
  std::uniform_real_distribution<float> inner(-0.5f * extent_m, 0.5f * extent_m);
  std::vector<Scan> out(scans);
  for (int s = 0; s < scans; ++s) {
    out[s].pose.position = {inner(rng), inner(rng), inner(rng)};
    out[s].source = "random-" + std::to_string(seed) + "-" + std::to_string(s);
    for (int i = 0; i < points_per_scan; ++i) out[s].points.push_back({coord(rng), coord(rng), coord(rng)});
  }
  return out;
}

BuildParams small_params(int depth) {
  BuildParams p;
  p.grid.resolution_m = 0.1;
  p.grid.block_depth = depth;
  p.preprocess.end_margin_m = 0.1;
  p.preprocess.max_range_m = 2.5;
  return p;
}

std::vector<ScanObservations> observations_of(const std::vector<Scan>& scans, const BuildParams& params) {
  std::vector<ScanObservations> out(scans.size());
  PreprocessCounts counts;
  for (size_t i = 0; i < scans.size(); ++i) preprocess_scan(scans[i], params.preprocess, out[i], counts);
  return out;
}

void expect_gp_not_positive_definite(const CommandResult& r, const std::string& what, const std::string& output) {
  EXPECT_EQ(r.status, 1) << what << "\n" << r.output;
  EXPECT_EQ(r.output.rfind("bgkmap: error: GP: the kernel matrix is not positive definite", 0), 0u) << r.output;
  EXPECT_NE(r.output.find("raise --gp-noise"), std::string::npos) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  EXPECT_FALSE(std::filesystem::exists(output)) << what;
}

CommandResult run_command(const std::string& command_line) {
  CommandResult r;
  FILE* pipe = popen((command_line + " 2>&1").c_str(), "r");
  if (!pipe) return r;
  char buffer[4096];
  size_t n;
  while ((n = fread(buffer, 1, sizeof buffer, pipe)) > 0) r.output.append(buffer, n);
  const int status = pclose(pipe);
  r.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

std::vector<Scan> two_planar_scans() {
  std::vector<Scan> scans(2);
  scans[0].pose.position = {1.5f, 1.5f, 0.0f};
  scans[1].pose.position = {1.8f, 1.6f, 0.0f};
  for (int s = 0; s < 2; ++s)
    for (int i = 0; i < 8; ++i) {
      const double a = 0.8 * i + s, r = 0.35 + 0.05 * (i % 3);
      const Vec3f o = scans[s].pose.position;
      scans[s].points.push_back({static_cast<float>(o.x + r * std::cos(a)), static_cast<float>(o.y + r * std::sin(a)), 0.0f});
    }
  return scans;
}

BuildParams small_planar_params() {
  BuildParams params;
  params.grid.resolution_m = 0.1;
  params.grid.block_depth = 6;
  params.preprocess.max_range_m = 0;
  params.preprocess.end_margin_m = 0.05f;
  return params;
}

}  // namespace bgkmap::testing
