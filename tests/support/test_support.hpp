// Helpers shared by the test executables.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "bgkmap/map/bgk_map.hpp"
#include "bgkmap/core/params.hpp"
#include "bgkmap/core/scan.hpp"
#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/integrate/observations.hpp"

namespace bgkmap::testing {

// The shared datasets folder by datasets/locate.py's rule: $BGKMAP_DATASETS, else the build's
// default (CMake BGKMAP_DATASETS_DIR: ../shared/datasets beside the checkout).
std::filesystem::path datasets_dir();

// True when CI=true: missing shared data is then a failure, not a skip.
bool running_in_ci();

// A fresh empty folder under the system temp dir, removed by the caller if wanted.
std::filesystem::path make_temp_dir(const std::string& tag);

// The OpenMP CPU back end on `threads` threads.
BackendOptions cpu_backend(int threads = 2);

// A fresh temp folder (make_temp_dir), removed with everything in it when this goes out of scope.
class TempDir {
 public:
  explicit TempDir(const std::string& tag) : path_(make_temp_dir(tag)) {}
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

// A file's bytes (empty when it cannot be read).
std::string read_bytes(const std::filesystem::path& file);

// Writes `bytes` as a new file (removed first: ext4 flushes files truncated and rewritten).
void write_bytes(const std::filesystem::path& file, const std::string& bytes);

// Every scan a ScanSource gives for these inputs.
std::vector<Scan> read_all_scans(const std::vector<std::filesystem::path>& inputs);

// Runs `action`, which must throw InputError naming `file` in a one-line message (and not one
// of running out of memory: corrupt counts must be caught by the checks). Any other exception is
// a failure; a crash ends the test program.
void expect_input_error(const std::filesystem::path& file, const std::function<void()>& action,
                        const std::string& context);

// A random scene: `scans` scans of `points_per_scan` points scattered in a box, with origins
// inside it; deterministic for a seed.
std::vector<Scan> random_scans(uint32_t seed, int scans, int points_per_scan, float extent_m = 3.0f);

// The GP methods' small planar scene: two scans at z = 0, 0.3 m apart, of 8 returns each 0.35-0.45 m
// from their origin, inside one block of 32 x 32 x 32 cells of 0.1 m (small_planar_params: no
// range limit, 0.05 m end margin), so a local model of 100 neighbours holds every datum.
std::vector<Scan> two_planar_scans();
BuildParams small_planar_params();

// The back-end tests' small maps: 0.1 m cells, blocks of 2^(depth-1) cells per side, end margin
// 0.1 m, max range 2.5 m.
BuildParams small_params(int depth = 3);

// Each scan preprocessed as the Mapper does: the observations a brute-force reference sums over.
std::vector<ScanObservations> observations_of(const std::vector<Scan>& scans, const BuildParams& params);

// Same blocks in the same slots and every alpha and beta bit for bit (the parameters aside).
void expect_same_cells(const BgkMap& expected, const BgkMap& actual);

// Runs a shell command line: its exit code (-1 when it did not exit normally) and its stdout and
// stderr together.
struct CommandResult {
  int status = -1;
  std::string output;
};
CommandResult run_command(const std::string& command_line);

// A GP build ended by a kernel matrix that is not positive definite: exit 1, one line naming
// --gp-noise as the remedy, and no `output` written. `what` names the case in failures.
void expect_gp_not_positive_definite(const CommandResult& r, const std::string& what, const std::string& output);

}  // namespace bgkmap::testing

// Declares `dir_var` as the shared datasets folder; if it is missing, fails the test under
// CI=true and skips it elsewhere.
#define BGKMAP_REQUIRE_DATASETS(dir_var)                                                        \
  const std::filesystem::path dir_var = ::bgkmap::testing::datasets_dir();                      \
  if (!std::filesystem::is_directory(dir_var)) {                                                \
    if (::bgkmap::testing::running_in_ci()) FAIL() << "shared datasets missing: " << dir_var;    \
    GTEST_SKIP() << "shared datasets missing (set BGKMAP_DATASETS): " << dir_var;               \
  }
