// The bgkmap command as a user runs it: config files and flags, the report, errors, resume.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "bgkmap/io/pcd_io.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

using Result = testing::CommandResult;

// The bgkmap command with these arguments.
Result run(const std::string& args) { return testing::run_command(std::string(BGKMAP_CLI) + " " + args); }

class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::make_temp_dir("cli");
    const auto scans = testing::random_scans(3, 3, 200, 1.5f);
    std::filesystem::create_directories(dir_ / "scans");
    for (size_t i = 0; i < scans.size(); ++i) write_pcd(dir_ / "scans" / ("s_" + std::to_string(i + 1) + ".pcd"), scans[i]);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  nlohmann::json report(const std::string& name) const {
    std::ifstream in(dir_ / name);
    return nlohmann::json::parse(in);
  }
  std::filesystem::path dir_;
};

TEST_F(Cli, ConfigFileThenFlagsOverrideIt) {
  {
    std::ofstream cfg(dir_ / "p.yaml");
    cfg << "resolution: 0.2\nmax-range: 2.5\nbeyond-range: drop\nend_margin: 0.05\nell: 0.3\nthreads: 1\n";
  }
  const Result r = run("build -q " + path("scans") + " -o " + path("m.bgk") + " --report " + path("r.json") +
                       " --config " + path("p.yaml") + " --ell 0.4 --backend cpu");
  ASSERT_EQ(r.status, 0) << r.output;
  const nlohmann::json params = report("r.json")["params"];
  EXPECT_DOUBLE_EQ(params["resolution"].get<double>(), 0.2);        // from the file
  EXPECT_DOUBLE_EQ(params["max_range"].get<double>(), 2.5);          // dashes accepted
  EXPECT_DOUBLE_EQ(params["end_margin"].get<double>(), 0.05);        // underscores accepted
  EXPECT_EQ(params["beyond_range"], "drop");
  EXPECT_NEAR(params["ell"].get<double>(), 0.4, 1e-7);               // the flag wins
  EXPECT_EQ(params["threads"].get<int>(), 1);
  EXPECT_EQ(report("r.json")["backend"]["threads"].get<int>(), 1);
}

// Spinning OpenMP threads made 2 threads 7-50x slower than 1 when another process kept a core
// busy; the build restarts itself with passive waiting, which the runtime must really see (it
// prints its settings under OMP_DISPLAY_ENV, once per process: the restarted one last).
TEST_F(Cli, BuildRunsOpenMpWithPassiveWaitingUnlessTheUserChose) {
  const std::string build = std::string(BGKMAP_CLI) + " build -q " + path("scans") + " -o " + path("m.bgk") +
                            " --backend cpu --threads 2 --report " + path("r.json");
  Result r = testing::run_command("env -u OMP_WAIT_POLICY -u GOMP_SPINCOUNT OMP_DISPLAY_ENV=verbose " + build);
  ASSERT_EQ(r.status, 0) << r.output;
  const size_t last = r.output.rfind("GOMP_SPINCOUNT = ");
  ASSERT_NE(last, std::string::npos) << r.output;
  EXPECT_EQ(r.output.substr(last, 20), "GOMP_SPINCOUNT = '0'") << r.output;
  EXPECT_EQ(report("r.json")["backend"]["omp_wait_policy"], "passive");
  r = testing::run_command("env -u GOMP_SPINCOUNT OMP_WAIT_POLICY=active " + build);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(report("r.json")["backend"]["omp_wait_policy"], "active");
  r = testing::run_command("env -u OMP_WAIT_POLICY GOMP_SPINCOUNT=1000 " + build);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(report("r.json")["backend"]["omp_wait_policy"], "spin 1000");
}

TEST_F(Cli, ConfigChoosesTheMethodAndItsParametersAndFlagsOverrideThem) {
  {
    std::ofstream cfg(dir_ / "m.yaml");
    cfg << "method: octomap\nprob_hit: 0.8\nprob-miss: 0.35\nclamp_max: 0.95\nmax_range: 2.5\n";
  }
  Result r = run("build -q " + path("scans") + " -o " + path("m.ot") + " --report " + path("r.json") + " --config " +
                 path("m.yaml") + " --prob-miss 0.3");
  ASSERT_EQ(r.status, 0) << r.output;
  nlohmann::json params = report("r.json")["params"];
  EXPECT_EQ(params["method"], "octomap");                          // from the file
  EXPECT_DOUBLE_EQ(params["prob_hit"].get<double>(), 0.8);          // from the file
  EXPECT_DOUBLE_EQ(params["prob_miss"].get<double>(), 0.3);         // the flag wins
  EXPECT_DOUBLE_EQ(params["clamp_max"].get<double>(), 0.95);
  EXPECT_DOUBLE_EQ(params["clamp_min"].get<double>(), 0.1192);      // OctoMap's default
  {
    std::ofstream cfg(dir_ / "g.yaml");
    cfg << "method: gpoctomap\nfree_resolution: 0.3\ngp_noise: 0.2\ngp-squash: 0.5\nmax_range: 2.5\n";
  }
  // --method overrides the file's method; the file's method parameters still apply.
  r = run("build -q " + path("scans") + " -o " + path("g.bgk") + " --report " + path("g.json") + " --config " +
          path("g.yaml") + " --method bgk --backend cpu");
  ASSERT_EQ(r.status, 0) << r.output;
  params = report("g.json")["params"];
  EXPECT_EQ(params["method"], "bgk");
  EXPECT_DOUBLE_EQ(params["free_resolution"].get<double>(), 0.3);
  r = run("build -q " + path("scans") + " -o " + path("g.ot") + " --report " + path("g2.json") + " --config " +
          path("g.yaml") + " --gp-noise 0.15 --threads 1 --ds 0.1");
  ASSERT_EQ(r.status, 0) << r.output;
  params = report("g2.json")["params"];
  EXPECT_EQ(params["method"], "gpoctomap");
  EXPECT_DOUBLE_EQ(params["gp_noise"].get<double>(), 0.15);
  EXPECT_DOUBLE_EQ(params["gp_squash"].get<double>(), 0.5);
}

TEST_F(Cli, ConfigMethodKeysWithBadValuesAreRefusedNamingFileAndKey) {
  const auto refused = [&](const std::string& yaml, const std::string& expected) {
    {
      std::ofstream cfg(dir_ / "bad.yaml");
      cfg << yaml;
    }
    const Result r = run("build -q " + path("scans") + " -o " + path("m.ot") + " --config " + path("bad.yaml"));
    EXPECT_EQ(r.status, 1) << yaml;
    EXPECT_NE(r.output.find("bad.yaml"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(expected), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  };
  refused("method: octomapp\n", "method 'octomapp'");
  refused("method: octomap\nprob_hit: high\n", "prob_hit");
  refused("method: octomap\nprob_hti: 0.8\n", "unknown parameter 'prob_hti'");
  refused("[resolution, ell]: 0.2\n", "line 1: a parameter name must be a plain word");  // found by fuzz_config_yaml
  refused("ell: 0.2\n{a: 1}: 2\n", "line 2: a parameter name must be a plain word");
  // Values out of range name the file, not a flag that was never given.
  refused("ell: -1\n", "ell");
  refused("method: bhm\nbhm-gamma: -1\n", "bad.yaml: bhm-gamma must be > 0");  // as the file spells it
  refused("method: bhm\nbhm_gamma: -1\n", "bad.yaml: bhm_gamma must be > 0");
  refused("threads: -3\n", "'threads' must be >= 0");
  refused("2d: true\nplane_z: .inf\n", "finite");
  EXPECT_FALSE(std::filesystem::exists(dir_ / "m.ot"));
}

// Infinite values passed the "> 0" checks and gave an empty map with status 0, or aborted the
// process (bhm-prior-var inf: a posterior precision thrown inside an OpenMP loop); values whose
// squares or inverses overflow did the same. bhm-spacing 1e6 never ended (the map's writing
// visited every cell of its huge tiles) and 1e-4 ended in std::bad_alloc after 30 s (the memory
// estimate listed every block each point reaches). Each is refused in one line naming its flag.
TEST_F(Cli, MethodParametersThatAreInfiniteOrOverflowAreRefusedNamingTheFlag) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"--method bhm --bhm-prior-var inf", "bhm-prior-var must be in [1e-06, 1e+06]"},
      {"--method bhm --bhm-prior-var 1e-300", "bhm-prior-var must be in"},
      {"--method gpom --gp-signal inf", "gp-signal must be in (0, 1e+06]"},
      {"--method gpom --gp-signal 1e300", "gp-signal must be in"},
      {"--method gpom --gp-noise inf", "gp-noise must be in (0, 1000]"},
      {"--method gpom --gp-range-sigma 1e200", "gp-range-sigma must be in [0, 100] m"},
      {"--method gpom --gp-length inf", "gp-length must be > 0 and finite"},
      {"--method bhm --bhm-gamma inf", "bhm-gamma must be > 0 and finite"},
      {"--method bhm --bhm-spacing inf", "bhm-spacing must be > 0 and finite"},
      {"--method bhm --bhm-support-var inf", "bhm-support-var must be >= 0 and finite"},
      {"--method bgk --free-resolution inf", "free-resolution must be > 0 and finite"},
      {"--method bhm --bhm-spacing 1e-4", "bhm-spacing 0.0001 m puts 1.38e+08 hinges within reach of a point"},
      {"--method bhm --bhm-spacing 1e6", "--bhm-spacing 1e+06 m makes a block's tile"},
  };
  for (const auto& [flags, expected] : cases) {
    const Result r = run("build -q " + path("scans") + " -o " + path("m.bt") + " --threads 2 " + flags);
    EXPECT_EQ(r.status, 1) << flags << "\n" << r.output;
    EXPECT_EQ(r.output.rfind("bgkmap: error: ", 0), 0u) << r.output;
    EXPECT_NE(r.output.find(expected), std::string::npos) << flags << "\n" << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_FALSE(std::filesystem::exists(dir_ / "m.bt")) << flags;
  }
  // The bounds themselves are taken (--gp-range-sigma 100 too, but its expected kernel takes
  // minutes in 3-D).
  for (const std::string flags : {"--method gpom --gp-noise 1000 --gp-signal 1e6",
                                  "--method bhm --bhm-prior-var 1e-6", "--method bhm --bhm-prior-var 1e6"}) {
    const Result r = run("build -q " + path("scans") + " -o " + path("m.bt") + " --threads 2 --max-range 2 " + flags);
    EXPECT_EQ(r.status, 0) << flags << "\n" << r.output;
  }
}

// A scan whose bucketing would not fit is refused naming the flag that sets the reach: --ell for
// the BGK methods, --gp-length for gpom and wgpom (the message named --ell, which they ignore).
TEST_F(Cli, BucketingThatWouldNotFitNamesTheFlagThatSetsTheReach) {
  for (const auto& [flags, named] : std::vector<std::pair<std::string, std::string>>{
           {"--method gpom --gp-length 30 --max-memory 1G", "a smaller --gp-length or"},
           {"--method wgpom --gp-length 30 --max-memory 1G", "a smaller --gp-length or"},
           {"--method bgkl --backend cpu --max-memory 1M", "a smaller --ell or"}}) {
    const Result r = run("build -q " + path("scans") + " -o " + path("m.bt") + " --threads 2 " + flags);
    EXPECT_EQ(r.status, 1) << flags << "\n" << r.output;
    EXPECT_EQ(r.output.rfind("bgkmap: error: bucketing a scan", 0), 0u) << r.output;
    EXPECT_NE(r.output.find(named), std::string::npos) << flags << "\n" << r.output;
  }
}

TEST_F(Cli, ReportHasEveryDocumentedField) {
  const Result r = run("build -q " + path("scans") + " -o " + path("m.bgk") + " -o " + path("m.ot") + " --report " +
                       path("r.json") + " --backend cpu --max-range 2.5");
  ASSERT_EQ(r.status, 0) << r.output;
  const nlohmann::json j = report("r.json");
  for (const char* key : {"resolution", "block_depth", "ell", "sigma0", "prior_alpha", "prior_beta", "ds", "max_range",
                          "beyond_range", "end_margin", "occupied_threshold", "free_threshold", "var_threshold", "threads", "backend"})
    EXPECT_TRUE(j["params"].contains(key)) << key;
  for (const char* key : {"scans", "points_read", "dropped_nonfinite", "beyond_max_range", "hits", "beams",
                          "blocks_touched", "pairs_evaluated", "pairs_within_l"})
    EXPECT_TRUE(j["counts"].contains(key)) << key;
  for (const char* key : {"read_s", "insert_s", "preprocess_s", "bucket_s", "compute_s", "update_s", "per_scan"})
    EXPECT_TRUE(j["timing"].contains(key)) << key;
  EXPECT_EQ(j["counts"]["scans"].get<int>(), 3);
  EXPECT_EQ(j["counts"]["points_read"].get<int>(), 600);
  EXPECT_EQ(j["timing"]["per_scan"].size(), 3u);
  EXPECT_GT(j["counts"]["beyond_max_range"].get<int>(), 0);
  EXPECT_EQ(j["backend"]["name"], "cpu");
  EXPECT_GT(j["peak_rss_mb"].get<double>(), 0);
  const double parts = j["timing"]["preprocess_s"].get<double>() + j["timing"]["bucket_s"].get<double>() +
                       j["timing"]["compute_s"].get<double>() + j["timing"]["update_s"].get<double>();
  EXPECT_LE(parts, j["timing"]["insert_s"].get<double>() * 1.0001 + 1e-6);
}

// The Intel Research Lab log mapped out of the box (3-D): every scan, the no-return readings
// as free beams beyond the 20 m max range (never hits), the other messages counted.
TEST_F(Cli, BuildsTheIntelLogOutOfTheBox) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  const Result r = run("build -q " + (datasets / "carmen/intel-corrected.log.gz").string() + " -o " + path("intel.bgk") +
                       " --max-range 20 --backend cpu --report " + path("r.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  const nlohmann::json c = report("r.json")["counts"];
  EXPECT_EQ(c["scans"].get<int>(), 910);
  EXPECT_EQ(c["points_read"].get<int>(), 910 * 180);
  EXPECT_EQ(c["no_returns"].get<int>(), 4172);
  EXPECT_EQ(c["no_returns_dropped"].get<int>(), 0);
  EXPECT_GE(c["beyond_max_range"].get<int>(), 4172);  // and the returns beyond 20 m
  EXPECT_EQ(c["hits"].get<int>() + c["beyond_max_range"].get<int>(), 910 * 180);
  EXPECT_EQ(c["skipped_messages"]["ODOM"].get<int>(), 14541);
  EXPECT_TRUE(std::filesystem::exists(dir_ / "intel.bgk"));
  // Without --max-range the no returns are dropped, with a note saying so.
  const Result bare = run("build " + (datasets / "carmen/intel-corrected.log.gz").string() + " -o " + path("bare.bgk") +
                          " --backend cpu --report " + path("bare.json"));
  ASSERT_EQ(bare.status, 0) << bare.output;
  EXPECT_EQ(report("bare.json")["counts"]["no_returns_dropped"].get<int>(), 4172);
  EXPECT_EQ(report("bare.json")["counts"]["hits"].get<int>(), 910 * 180 - 4172);
  EXPECT_NE(bare.output.find("4172 no-return readings dropped"), std::string::npos) << bare.output;
}

// The other real-data inputs build out of the box: a KITTI sequence folder, a PLY with --origin,
// XYZ files with --poses, an OctoMap text log.
TEST_F(Cli, BuildsKittiPlyXyzAndOctomapLogInputs) {
  const std::filesystem::path seq = dir_ / "kitti" / "00";
  std::filesystem::create_directories(seq / "velodyne");
  testing::write_bytes(seq / "calib.txt", "Tr: 0 -1 0 0 0 0 -1 0 1 0 0 0\n");
  testing::write_bytes(seq / "poses.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 0.5\n");
  for (const char* name : {"000000.bin", "000001.bin"}) {
    std::string bytes;
    for (int i = 0; i < 50; ++i) {
      const float p[4] = {2.0f + 0.02f * i, -1.0f + 0.04f * i, 0.3f, 0.0f};
      bytes.append(reinterpret_cast<const char*>(p), sizeof p);
    }
    testing::write_bytes(seq / "velodyne" / name, bytes);
  }
  testing::write_bytes(dir_ / "a.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                       "property float z\nend_header\n1 0 0\n0 1 0\n1 1 0.5\n");
  testing::write_bytes(dir_ / "a.xyz", "1 0 0\n2 0 0\n");
  testing::write_bytes(dir_ / "b.xyz", "0 1 0\n");
  testing::write_bytes(dir_ / "poses.txt", "0 0 0 0 0 0 0 1\n0.1 0 0 0.2 0 0 0 1\n");
  testing::write_bytes(dir_ / "scan.dat", "NODE 0 0 0 0 0 0\n1 0 0\n0 1 0\nNODE 0.5 0 0 0 0 1.57\n1 0 0\n");
  const std::vector<std::pair<std::string, int>> runs = {{path("kitti/00"), 2},
                                                         {path("a.ply") + " --origin 0,0,0.2", 1},
                                                         {path("a.xyz") + " " + path("b.xyz") + " --poses " + path("poses.txt"), 2},
                                                         {path("scan.dat"), 2}};
  for (const auto& [inputs, scans] : runs) {
    const Result r = run("build -q " + inputs + " -o " + path("m.bgk") + " --backend cpu --report " + path("r.json"));
    ASSERT_EQ(r.status, 0) << inputs << ": " << r.output;
    EXPECT_EQ(report("r.json")["counts"]["scans"].get<int>(), scans) << inputs;
    EXPECT_GT(report("r.json")["counts"]["hits"].get<int>(), 0) << inputs;
  }
  // --poses lines with covariances and a constant --pose-sigma: the map would record the unused one.
  testing::write_bytes(dir_ / "poses_cov.txt", "0 0 0 0 0 0 0 1 1e-4 0 0 0 1e-4 0 0 0 1e-6\n"
                                               "0.1 0 0 0.2 0 0 0 1 1e-4 0 0 0 1e-4 0 0 0 1e-6\n");
  const Result both = run("build -q " + path("a.xyz") + " " + path("b.xyz") + " --poses " + path("poses_cov.txt") +
                          " --pose-sigma 0.3,0.1 -o " + path("p.bgk") + " --backend cpu");
  EXPECT_EQ(both.status, 1) << both.output;
  EXPECT_NE(both.output.find("--poses with covariances), not both"), std::string::npos) << both.output;
  EXPECT_FALSE(std::filesystem::exists(dir_ / "p.bgk"));
  // --skip-bad-inputs passes over a sequence whose scan is cut (its error names the .bin inside).
  const std::filesystem::path bad = dir_ / "kitti" / "01";
  std::filesystem::create_directories(bad / "velodyne");
  std::filesystem::copy(seq / "calib.txt", bad / "calib.txt");
  std::filesystem::copy(seq / "poses.txt", bad / "poses.txt");
  testing::write_bytes(bad / "velodyne" / "000000.bin", std::string(17, '\0'));
  testing::write_bytes(bad / "velodyne" / "000001.bin", std::string(16, '\0'));
  const Result skipped = run("build -q " + bad.string() + " " + seq.string() + " -o " + path("m.bgk") +
                             " --backend cpu --skip-bad-inputs --report " + path("r.json"));
  ASSERT_EQ(skipped.status, 0) << skipped.output;
  EXPECT_NE(skipped.output.find("skipping bad input " + (bad / "velodyne" / "000000.bin").string()), std::string::npos)
      << skipped.output;
  EXPECT_EQ(report("r.json")["counts"]["scans"].get<int>(), 2);
  const Result bare = run("build -q " + path("a.ply") + " -o " + path("m.bgk"));
  EXPECT_EQ(bare.status, 1);
  EXPECT_NE(bare.output.find("a.ply: PLY and XYZ files carry no sensor origin"), std::string::npos) << bare.output;
}

TEST_F(Cli, BadInputGivesOneLineErrorNonZeroExitAndNoOutput) {
  {
    std::ofstream bad(dir_ / "scans" / "s_9.pcd");
    bad << "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 5\nHEIGHT 1\nPOINTS 5\nDATA binary\n";
  }
  // --threads 8 reads ahead on a thread of its own: the error comes from there.
  for (const char* threads : {"1", "8"}) {
    const Result r = run("build -q " + path("scans") + " -o " + path("m.bgk") + " --backend cpu --threads " + threads);
    EXPECT_EQ(r.status, 1);
    EXPECT_NE(r.output.find("s_9.pcd"), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_FALSE(std::filesystem::exists(dir_ / "m.bgk"));
  }
  for (const auto& entry : std::filesystem::directory_iterator(dir_))
    EXPECT_EQ(entry.path().string().find(".tmp-"), std::string::npos) << entry.path();
}

// Output paths are checked before any scan is read: a missing folder is named with the system's
// reason even when an input is corrupt too, and no output of the build is written.
TEST_F(Cli, UnwritableOutputsAreRefusedBeforeAnyWork) {
  {
    std::ofstream bad(dir_ / "scans" / "s_9.pcd");
    bad << "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 5\n";
  }
  for (const std::string& outputs : {" -o " + path("m.bgk") + " -o " + path("missing/m.ot"),
                                     " -o " + path("m.bgk") + " --report " + path("missing/r.json")}) {
    const Result r = run("build -q " + path("scans") + outputs + " --backend cpu");
    EXPECT_EQ(r.status, 1);
    EXPECT_EQ(r.output, "bgkmap: error: " + path("missing") + (outputs.find("r.json") != std::string::npos ? "/r.json" : "/m.ot") +
                            ": cannot write into folder " + path("missing") + " (No such file or directory)\n");
    EXPECT_FALSE(std::filesystem::exists(dir_ / "m.bgk"));
  }
  const Result sim = run("simulate structured -q -o " + path("scans/s_1.pcd/sim"));
  EXPECT_EQ(sim.status, 1);
  EXPECT_NE(sim.output.find("(Not a directory)"), std::string::npos) << sim.output;
  const Result eval = run("eval " + path("m.bgk") + " --truth " + path("t.bt") + " --json " + path("missing/e.json"));
  EXPECT_EQ(eval.status, 1);
  EXPECT_NE(eval.output.find("missing/e.json: cannot write into folder"), std::string::npos) << eval.output;
}

// --report /dev/stdout writes the report through to standard output; the link is not replaced.
TEST_F(Cli, ReportToDevStdoutIsWrittenThrough) {
  const bool was_link = std::filesystem::is_symlink("/dev/stdout");
  const Result r = run("build -q " + path("scans") + " -o " + path("m.bgk") + " --backend cpu --report /dev/stdout");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(nlohmann::json::parse(r.output)["counts"]["scans"].get<int>(), 3);
  EXPECT_EQ(std::filesystem::is_symlink("/dev/stdout"), was_link);
  EXPECT_FALSE(std::filesystem::is_regular_file(std::filesystem::symlink_status("/dev/stdout")));
}

// --skip-bad-inputs: a truncated PCD among good ones is passed over, named on stderr once and
// listed in the report; the map is the one built without it.
TEST_F(Cli, SkipBadInputsPassesOverATruncatedPcd) {
  const std::string flags = " --backend cpu --max-range 2.5";
  ASSERT_EQ(run("build -q " + path("scans") + " -o " + path("good.bgk") + flags).status, 0);
  write_pcd(dir_ / "s_2b.pcd", testing::random_scans(5, 1, 200, 1.5f)[0]);
  const std::string bytes = testing::read_bytes(dir_ / "s_2b.pcd");
  {
    std::ofstream cut(dir_ / "scans" / "s_2b.pcd", std::ios::binary);  // between s_2 and s_3
    cut << bytes.substr(0, bytes.size() - 100);
  }
  const Result stopped = run("build -q " + path("scans") + " -o " + path("m.bgk") + flags);
  EXPECT_EQ(stopped.status, 1);
  EXPECT_NE(stopped.output.find("s_2b.pcd: PCD: truncated binary data"), std::string::npos) << stopped.output;
  EXPECT_FALSE(std::filesystem::exists(dir_ / "m.bgk"));

  for (const char* threads : {"1", "8"}) {  // 8: read on a thread of its own
    const Result r = run("build -q " + path("scans") + " -o " + path("m.bgk") + " --report " + path("r.json") + flags +
                         " --skip-bad-inputs --threads " + threads);
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_EQ(r.output.rfind("bgkmap: skipping bad input " + path("scans/s_2b.pcd") + ": PCD: truncated binary data", 0), 0u) << r.output;
    const nlohmann::json j = report("r.json");
    EXPECT_EQ(j["counts"]["scans"].get<int>(), 3);
    EXPECT_EQ(j["counts"]["inputs_skipped"].get<int>(), 1);
    ASSERT_EQ(j["skipped_inputs"].size(), 1u);
    EXPECT_EQ(j["skipped_inputs"][0]["path"], path("scans/s_2b.pcd"));
    EXPECT_EQ(testing::read_bytes(dir_ / "m.bgk"), testing::read_bytes(dir_ / "good.bgk"));
  }
  const Result none = run("build -q " + path("scans/s_2b.pcd") + " -o " + path("x.bgk") + flags + " --skip-bad-inputs");
  EXPECT_EQ(none.status, 1);
  EXPECT_NE(none.output.find("no input could be read (1 skipped as bad)"), std::string::npos) << none.output;
}

// --skip-bad-inputs with --pose-covariance: a PCD that cannot be read passes over its own line, so
// the next scans keep theirs (the map is the one of the good scans with their lines); a covariance
// file that does not fit the scans ends the run with one error (it was "skipped" without end).
TEST_F(Cli, SkipBadInputsKeepsTheCovarianceLinesInStep) {
  const std::string flags = " --backend cpu --max-range 2.5 --pose-fusion kernel";
  std::vector<std::string> lines;
  {
    ScanSource good({dir_ / "scans"});
    Scan scan;
    while (good.next(scan)) {
      char line[256];
      std::snprintf(line, sizeof line, "0 %.9g %.9g %.9g %.9g %.9g %.9g %.9g ", scan.pose.position.x,
                    scan.pose.position.y, scan.pose.position.z, scan.pose.qx, scan.pose.qy, scan.pose.qz, scan.pose.qw);
      lines.push_back(line + std::to_string(1e-3 * double(lines.size() + 1)) + " 0 0 0 0.001 0 0 0 0.0001\n");
    }
  }
  ASSERT_EQ(lines.size(), 3u);
  const auto write_lines = [&](const std::string& name, const std::vector<std::string>& with) {
    std::ofstream out(dir_ / name);
    for (const std::string& l : with) out << l;
  };
  write_lines("cov3.txt", lines);
  write_lines("cov4.txt", {lines[0], lines[1], "0 9 9 9 0 0 0 1 1 0 0 0 1 0 0 0 1\n", lines[2]});  // s_2b's line
  ASSERT_EQ(run("build -q " + path("scans") + " -o " + path("good.bgk") + flags + " --pose-covariance " +
                path("cov3.txt")).status, 0);
  std::ofstream(dir_ / "scans" / "s_2b.pcd") << "not a PCD";  // between s_2 and s_3
  // Bounded in time and output: the loop this guards against printed a line each microsecond.
  const auto bounded = [](const std::string& args) {
    return testing::run_command("bash -c 'set -o pipefail; timeout 60 " + std::string(BGKMAP_CLI) + " " + args +
                                " 2>&1 | head -c 4000'");
  };
  const Result r = bounded("build -q " + path("scans") + " -o " + path("m.bgk") + flags +
                           " --skip-bad-inputs --pose-covariance " + path("cov4.txt"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  EXPECT_NE(r.output.find("skipping bad input " + path("scans/s_2b.pcd")), std::string::npos) << r.output;
  EXPECT_EQ(testing::read_bytes(dir_ / "m.bgk"), testing::read_bytes(dir_ / "good.bgk"));

  const Result misfit = bounded("build -q " + path("scans") + " -o " + path("x.bgk") + flags +
                                " --skip-bad-inputs --pose-covariance " + path("cov3.txt"));
  EXPECT_EQ(misfit.status, 1);
  EXPECT_NE(misfit.output.find(path("cov3.txt") + ": 3 lines, but the inputs hold at least scan 4"), std::string::npos)
      << misfit.output;
  EXPECT_EQ(std::count(misfit.output.begin(), misfit.output.end(), '\n'), 2) << misfit.output;  // the skip, the error
  EXPECT_FALSE(std::filesystem::exists(dir_ / "x.bgk"));
  // A file of many scans that cannot be opened: how many lines it had is unknown, so the run stops.
  std::filesystem::remove(dir_ / "scans" / "s_2b.pcd");
  std::ofstream(dir_ / "scans" / "s_2b.graph") << "forty bytes that are not an OctoMap graph";
  const Result graph = bounded("build -q " + path("scans") + " -o " + path("x.bgk") + flags +
                               " --skip-bad-inputs --pose-covariance " + path("cov3.txt"));
  EXPECT_EQ(graph.status, 1) << graph.output;
  EXPECT_NE(graph.output.find(path("cov3.txt") + ": cannot tell which lines belong to the scans after 0 of " +
                              path("scans/s_2b.graph")), std::string::npos) << graph.output;
  EXPECT_FALSE(std::filesystem::exists(dir_ / "x.bgk"));
}

// With 8 or more host threads one of them reads and prepares the next scan (build_command.cpp):
// the same scans, in the same order, so the same bytes; the report keeps the threads asked for.
TEST_F(Cli, ReadingAheadBuildsTheSameMap) {
  const std::string flags = " --backend cpu --max-range 2.5 --ds 0.05";
  ASSERT_EQ(run("build -q " + path("scans") + " -o " + path("inline.bgk") + flags + " --threads 2").status, 0);
  const Result r = run("build -q " + path("scans") + " -o " + path("ahead.bgk") + flags + " --threads 8 --report " +
                       path("r.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(testing::read_bytes(dir_ / "inline.bgk"), testing::read_bytes(dir_ / "ahead.bgk"));
  const nlohmann::json j = report("r.json");
  EXPECT_EQ(j["params"]["threads"].get<int>(), 8);
  EXPECT_EQ(j["backend"]["threads"].get<int>(), 7);  // one reads ahead
  EXPECT_EQ(j["counts"]["scans"].get<int>(), 3);
}

TEST_F(Cli, UnknownConfigKeyAndBadOutputExtensionAreRefused) {
  {
    std::ofstream cfg(dir_ / "p.yaml");
    cfg << "resolutoin: 0.2\n";
  }
  Result r = run("build -q " + path("scans") + " -o " + path("m.bgk") + " --config " + path("p.yaml"));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("resolutoin"), std::string::npos) << r.output;
  r = run("build -q " + path("scans") + " -o " + path("m.png"));
  EXPECT_EQ(r.status, 2);  // a usage error: the name, not the file, is wrong
  EXPECT_NE(r.output.find("--output: " + path("m.png") + ": unknown map format"), std::string::npos) << r.output;
  r = run("build -q " + path("scans") + " -o " + path("m.bgk") + " --max-range 2 --beyond-range keep");
  EXPECT_EQ(r.status, 2);  // a usage error, as every flag of choices
  EXPECT_NE(r.output.find("--beyond-range: keep not in {free,drop}"), std::string::npos) << r.output;
}

TEST_F(Cli, ResumeEqualsOneBuildAndRefusesChangedParameters) {
  std::filesystem::create_directories(dir_ / "first");
  std::filesystem::copy(dir_ / "scans" / "s_1.pcd", dir_ / "first" / "s_1.pcd");
  std::filesystem::create_directories(dir_ / "rest");
  std::filesystem::copy(dir_ / "scans" / "s_2.pcd", dir_ / "rest" / "s_2.pcd");
  std::filesystem::copy(dir_ / "scans" / "s_3.pcd", dir_ / "rest" / "s_3.pcd");
  const std::string flags = " --backend cpu --max-range 2.5";
  ASSERT_EQ(run("build -q " + path("scans") + " -o " + path("all.bgk") + flags).status, 0);
  ASSERT_EQ(run("build -q " + path("first") + " -o " + path("part.bgk") + flags).status, 0);
  ASSERT_EQ(run("build -q " + path("rest") + " --resume " + path("part.bgk") + " -o " + path("resumed.bgk") + flags).status, 0);
  // Same cells and values: query a grid of points in both.
  {
    std::ofstream q(dir_ / "q.txt");
    for (int i = 0; i < 400; ++i) q << (i % 20) * 0.15 - 1.5 << " " << (i / 20) * 0.15 - 1.5 << " 0.05\n";
  }
  const Result a = run("query " + path("all.bgk") + " --points " + path("q.txt"));
  const Result b = run("query " + path("resumed.bgk") + " --points " + path("q.txt"));
  ASSERT_EQ(a.status, 0);
  EXPECT_EQ(a.output, b.output);
  const Result refused = run("build -q " + path("rest") + " --resume " + path("part.bgk") + " -o " + path("x.bgk") +
                             flags + " --ell 0.3");
  EXPECT_EQ(refused.status, 1);
  EXPECT_NE(refused.output.find("ell"), std::string::npos) << refused.output;
  const Result dropped = run("build -q " + path("rest") + " --resume " + path("part.bgk") + " -o " + path("x.bgk") +
                             flags + " --beyond-range drop");
  EXPECT_EQ(dropped.status, 1);
  EXPECT_NE(dropped.output.find("cannot change 'beyond_range'"), std::string::npos) << dropped.output;
}

// --2d from the command line and from a config file: the same planar map, its parameters in the
// report, queries at any height answered for the layer, and resuming refuses a change of plane
// or a 3-D map made planar.
TEST_F(Cli, PlanarMapsFromFlagsOrConfigAndResumeKeepsThePlane) {
  const std::string flags = " --backend cpu --max-range 2.5";
  ASSERT_EQ(run("build -q " + path("scans") + " -o " + path("flag.bgk") + flags + " --2d --plane-z 0.26 --report " +
                path("r.json"))
                .status,
            0);
  {
    std::ofstream config(dir_ / "planar.yaml");
    config << "2d: true\nplane_z: 0.21\n";
  }
  ASSERT_EQ(run("build -q " + path("scans") + " -o " + path("config.bgk") + flags + " --config " + path("planar.yaml"))
                .status,
            0);
  const nlohmann::json params = report("r.json")["params"];
  EXPECT_TRUE(params["planar"].get<bool>());
  EXPECT_NEAR(params["plane_z"].get<double>(), 0.25, 1e-12);  // the centre plane of the layer holding 0.26
  {
    std::ofstream q(dir_ / "q.txt");
    for (int i = 0; i < 200; ++i) q << (i % 20) * 0.15 - 1.5 << " " << (i / 20) * 0.15 - 0.7 << " 0.25\n";
    std::ofstream q_high(dir_ / "q_high.txt");
    for (int i = 0; i < 200; ++i) q_high << (i % 20) * 0.15 - 1.5 << " " << (i / 20) * 0.15 - 0.7 << " 9.0\n";
  }
  const Result a = run("query " + path("flag.bgk") + " --points " + path("q.txt"));
  const Result b = run("query " + path("config.bgk") + " --points " + path("q.txt"));
  ASSERT_EQ(a.status, 0) << a.output;
  EXPECT_EQ(a.output, b.output);
  EXPECT_NE(a.output.find("occupied"), std::string::npos);
  // The cell centres printed differ in z only; the posteriors are the layer's.
  const Result high = run("query " + path("flag.bgk") + " --points " + path("q_high.txt"));
  ASSERT_EQ(high.status, 0);
  EXPECT_EQ(high.output, a.output);
  const Result moved = run("build -q " + path("scans") + " --resume " + path("flag.bgk") + " -o " + path("x.bgk") + flags +
                           " --2d --plane-z 1.0");
  EXPECT_EQ(moved.status, 1);
  EXPECT_NE(moved.output.find("cannot change 'plane_z'"), std::string::npos) << moved.output;
  ASSERT_EQ(run("build -q " + path("scans") + " -o " + path("three_d.bgk") + flags).status, 0);
  const Result made_planar = run("build -q " + path("scans") + " --resume " + path("three_d.bgk") + " -o " +
                                 path("x.bgk") + flags + " --2d");
  EXPECT_EQ(made_planar.status, 1);
  EXPECT_NE(made_planar.output.find("cannot change 'planar'"), std::string::npos) << made_planar.output;
}

// Parameters whose kernel reaches thousands of blocks a point (bad_alloc inside OpenMP, or
// minutes of spinning) or whose cell keys overflow 32 bits are refused before any work.
TEST_F(Cli, ParametersBeyondTheKeyAndKernelLimitsAreRefusedNamingTheFlag) {
  for (const auto& [flags, flag] : std::vector<std::pair<std::string, std::string>>{
           {"--resolution 0.001", "--ell 0.2 m reaches 26 blocks"},
           {"--ell 100", "--ell 100 m reaches 125 blocks"},
           {"--ell 1e6", "--ell 1e+06 m reaches"},
           {"--resolution 0.0001 --kernel box", "--resolution must be in [0.001, 10000] m"}}) {
    const Result r = run("build -q " + path("scans") + " -o " + path("m.bgk") + " " + flags);
    EXPECT_NE(r.status, 0) << flags;
    EXPECT_NE(r.output.find(flag), std::string::npos) << flags << ": " << r.output;
    EXPECT_FALSE(std::filesystem::exists(path("m.bgk")));
  }
}

// Points at 1e30 or 3e9 m wrapped the 32-bit keys (signed overflow); now dropped and counted,
// and queries there refused with one line.
TEST_F(Cli, FarPointsAreDroppedAndCountedAndQueriesThereRefused) {
  Scan scan = testing::random_scans(9, 1, 50, 1.5f)[0];
  scan.points.push_back({1e30f, 0, 0});
  scan.points.push_back({0, 3e9f, 0});
  scan.points.push_back({0, 0, -2e6f});
  std::filesystem::create_directories(dir_ / "far");
  write_pcd(dir_ / "far" / "s.pcd", scan);
  Result r = run("build -q " + path("far") + " -o " + path("m.bgk") + " --report " + path("r.json") + " --backend cpu");
  ASSERT_EQ(r.status, 0) << r.output;
  const nlohmann::json counts = report("r.json")["counts"];
  EXPECT_EQ(counts["dropped_out_of_key_range"].get<int>(), 3);
  EXPECT_EQ(counts["points_read"].get<int>(), 53);
  for (const char* far : {"1e30 0 0", "-3e9 0 0", "0 0 1000001"}) {
    r = testing::run_command("echo '" + std::string(far) + "' | " + std::string(BGKMAP_CLI) + " query " + path("m.bgk"));
    EXPECT_NE(r.status, 0) << far;
    EXPECT_NE(r.output.find("beyond the map's key range"), std::string::npos) << r.output;
  }
  r = testing::run_command("echo '999999 0 0' | " + std::string(BGKMAP_CLI) + " query " + path("m.bgk"));
  EXPECT_EQ(r.status, 0) << r.output;
}

// --pose-sigma and --pose-covariance: in the report and config, refused where they would be
// ignored, a bad covariance file named with its line; a zero sigma is the plain map byte for byte.
TEST_F(Cli, PoseUncertaintyFlagsConfigAndRefusals) {
  const std::string build = "build -q " + path("scans") + " --backend cpu --threads 2 ";
  Result r = run(build + "-o " + path("plain.bgk"));
  ASSERT_EQ(r.status, 0) << r.output;
  r = run(build + "-o " + path("zero.bgk") + " --pose-sigma 0,0");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(testing::read_bytes(dir_ / "plain.bgk"), testing::read_bytes(dir_ / "zero.bgk"));

  r = run(build + "-o " + path("ek.bgk") + " --pose-sigma 0.05,0.02 --report " + path("r.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(report("r.json")["params"]["pose_sigma"], nlohmann::json({0.05, 0.02, 0.0, 0.0}));
  EXPECT_NE(testing::read_bytes(dir_ / "plain.bgk"), testing::read_bytes(dir_ / "ek.bgk"));
  {
    std::ofstream cfg(dir_ / "p.yaml");
    cfg << "pose_sigma: 0.05,0.02\n";
  }
  r = run(build + "-o " + path("ek_config.bgk") + " --config " + path("p.yaml"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(testing::read_bytes(dir_ / "ek.bgk"), testing::read_bytes(dir_ / "ek_config.bgk"));
  // --pose-fusion kernel: the expected kernel instead of the default expected sub-map, recorded.
  r = run(build + "-o " + path("ek_kernel.bgk") + " --pose-sigma 0.05,0.02 --pose-fusion kernel --report " +
          path("rk.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(report("rk.json")["params"]["pose_fusion"], "kernel");
  EXPECT_FALSE(report("r.json")["params"].contains("pose_fusion"));
  EXPECT_NE(testing::read_bytes(dir_ / "ek.bgk"), testing::read_bytes(dir_ / "ek_kernel.bgk"));
  {
    std::ofstream cfg(dir_ / "k.yaml");  // a key the defaults' JSON lacks (written only when not the default)
    cfg << "pose-sigma: 0.05,0.02\npose-fusion: kernel\n";
  }
  r = run(build + "-o " + path("ek_kernel_config.bgk") + " --config " + path("k.yaml"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(testing::read_bytes(dir_ / "ek_kernel.bgk"), testing::read_bytes(dir_ / "ek_kernel_config.bgk"));
  // Resuming a sub-map build with the kernel names the default rather than printing null.
  r = run(build + "-o " + path("ek.bgk") + " --resume " + path("ek.bgk") + " --pose-fusion kernel");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("cannot change 'pose_fusion' when resuming a map (stored the default, asked \"kernel\")"),
            std::string::npos) << r.output;
  r = run(build + "-o " + path("m.bgk") + " --pose-sigma 0.05,0.02 --pose-fusion mean");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("--pose-fusion: mean not in {submap,kernel}"), std::string::npos) << r.output;
  // Resuming with another pose sigma changes what alpha and beta mean.
  r = run(build + "-o " + path("ek.bgk") + " --resume " + path("ek.bgk") + " --pose-sigma 0.1,0.02");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("cannot change 'pose_sigma'"), std::string::npos) << r.output;

  r = run(build + "-o " + path("m.bt") + " --method octomap --pose-sigma 0.05,0.02");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("does not use a pose uncertainty"), std::string::npos) << r.output;
  r = run(build + "-o " + path("m.bgk") + " --kernel box --pose-sigma 0.05,0.02");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("sparse kernel"), std::string::npos) << r.output;
  r = run(build + "-o " + path("m.bgk") + " --pose-sigma 0.05");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("XY,YAW"), std::string::npos) << r.output;
  {
    std::ofstream cov(dir_ / "cov.txt");
    cov << "0 0 0 0 0 0 0 1 0.01 0 0\n";
  }
  r = run(build + "-o " + path("m.bgk") + " --pose-covariance " + path("cov.txt"));
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find(path("cov.txt") + ": line 1: poses: 11 fields"), std::string::npos) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  // Uncertainties that cannot be meant (squared, some overflow): refused before any work, named
  // by the flag, the config key or the file and line, where they once made a NaN bucketing error or
  // an empty map.
  const std::pair<std::string, std::string> huge[] = {
      {"--pose-sigma 1e40,0", "error: --pose-sigma '1e40,0': too large to be meant: x and y's standard deviation 1e+40 m"},
      {"--pose-sigma 1e155,0", "error: --pose-sigma '1e155,0': too large to be meant"},
      {"--pose-sigma 0,1e155", "error: --pose-sigma '0,1e155': too large to be meant: yaw's standard deviation"},
      {"--method gpom --pose-sigma 1e10,0", "error: --pose-sigma '1e10,0': too large to be meant"},
  };
  for (const auto& [flags, message] : huge) {
    r = run(build + "-o " + path("huge.bgk") + " " + flags);
    EXPECT_NE(r.status, 0) << flags;
    EXPECT_NE(r.output.find(message), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_FALSE(std::filesystem::exists(dir_ / "huge.bgk")) << flags;
  }
  {
    std::ofstream cfg(dir_ / "huge.yaml");
    cfg << "pose_sigma: 1e155,0\n";
    std::ofstream cov(dir_ / "cov.txt");
    cov << "# a covariance\n0 0 0 0 0 0 0 1 1e80 0 0 0 1e80 0 0 0 1e80\n";
  }
  r = run(build + "-o " + path("huge.bgk") + " --config " + path("huge.yaml"));
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find(path("huge.yaml") + ": pose_sigma '1e155,0': too large to be meant"), std::string::npos)
      << r.output;
  for (const char* fusion : {"submap", "kernel"}) {
    r = run(build + "-o " + path("huge.bgk") + " --pose-covariance " + path("cov.txt") + " --pose-fusion " + fusion);
    EXPECT_NE(r.status, 0);
    EXPECT_NE(r.output.find(path("cov.txt") + ": line 2: poses: the covariance is too large to be meant: x's standard "
                                              "deviation 1e+40 m is beyond the map's key range"),
              std::string::npos)
        << r.output;
  }
}

// simulate --drift writes poses with covariance that build --pose-covariance takes as they are.
TEST_F(Cli, SimulatedDriftBuildsWithItsCovariance) {
  Result r = run("simulate structured -q --sensor planar --scans 3 --truth-resolution 0 --drift 0.02,0.005 -o " +
                 path("sim"));
  ASSERT_EQ(r.status, 0) << r.output;
  ASSERT_TRUE(std::filesystem::exists(dir_ / "sim" / "poses_true.txt"));
  r = run("build -q " + path("sim/scans") + " --max-range 8 --backend cpu --threads 2 --pose-covariance " +
          path("sim/poses.txt") + " -o " + path("d.bgk") + " --report " + path("r.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(report("r.json")["counts"]["scans"].get<int>(), 3) << report("r.json").dump();
  EXPECT_EQ(report("r.json")["params"]["pose_covariance"], path("sim/poses.txt"));
  // The file's covariances would override the constant one the map records: refused.
  r = run("build -q " + path("sim/scans") + " --max-range 8 --backend cpu --pose-sigma 0.02,0.005 --pose-covariance " +
          path("sim/poses.txt") + " -o " + path("e.bgk"));
  EXPECT_NE(r.status, 0);
  const std::string give_one = "give a constant pose uncertainty (--pose-sigma, or the resumed map's pose_sigma) or "
                               "covariances per scan (--pose-covariance, --poses with covariances), not both";
  EXPECT_NE(r.output.find(give_one), std::string::npos) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  // The same when the constant one is a resumed map's.
  r = run("build -q " + path("sim/scans/scan_00000.pcd") + " --max-range 8 --backend cpu --pose-sigma 0.02,0.005 -o " +
          path("c.bgk"));
  ASSERT_EQ(r.status, 0) << r.output;
  r = run("build -q " + path("sim/scans") + " --max-range 8 --backend cpu --resume " + path("c.bgk") +
          " --pose-covariance " + path("sim/poses.txt") + " -o " + path("e.bgk"));
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find(give_one), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir_ / "e.bgk"));
  // simulate's suggested build line for a level planar laser makes a planar map.
  r = run("simulate structured --sensor planar --scans 1 --truth-resolution 0 --overwrite -o " + path("sim"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("--max-range 14 --2d --plane-z "), std::string::npos) << r.output;
}

// Without --max-range one point 100 km away made its beam cross 125,000 blocks: a 2 GB .bgk.
// Points farther than 1 km from their sensor are dropped and counted instead, and said once;
// with --max-range the same point is a free beam of that range, as any other.
TEST_F(Cli, PointsAKilometreAwayWithoutMaxRangeAreDroppedAndCounted) {
  const std::vector<Scan> scans = testing::random_scans(9, 1, 50, 1.5f);
  Scan far = scans[0];
  far.points.push_back({far.pose.position.x + 1e5f, far.pose.position.y, far.pose.position.z});
  std::filesystem::create_directories(dir_ / "near");
  std::filesystem::create_directories(dir_ / "far");
  write_pcd(dir_ / "near" / "s.pcd", scans[0]);
  write_pcd(dir_ / "far" / "s.pcd", far);
  ASSERT_EQ(run("build -q " + path("near") + " -o " + path("near.bgk") + " --report " + path("near.json") +
                " --backend cpu").status, 0);
  Result r = run("build " + path("far") + " -o " + path("far.bgk") + " --report " + path("far.json") + " --backend cpu");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("1 points farther than 1000 m from their sensor dropped: give --max-range"),
            std::string::npos) << r.output;
  nlohmann::json counts = report("far.json")["counts"];
  EXPECT_EQ(counts["dropped_beyond_reach"].get<int>(), 1);
  EXPECT_EQ(counts["points_read"].get<int>(), 51);
  EXPECT_EQ(counts["hits"].get<int>(), 50);
  EXPECT_EQ(counts["blocks_touched"], report("near.json")["counts"]["blocks_touched"]);
  EXPECT_LT(std::filesystem::file_size(path("far.bgk")), 2 * std::filesystem::file_size(path("near.bgk")));

  r = run("build -q " + path("far") + " -o " + path("far.bgk") + " --report " + path("far.json") +
          " --backend cpu --max-range 20");
  ASSERT_EQ(r.status, 0) << r.output;
  counts = report("far.json")["counts"];
  EXPECT_EQ(counts["dropped_beyond_reach"].get<int>(), 0);
  EXPECT_EQ(counts["beyond_max_range"].get<int>(), 1);
  EXPECT_EQ(counts["beams"].get<int>(), 51);
}

// Each method checks its big steps against --max-memory before taking them, naming what would
// not fit and the flags that would make it fit; no output is written.
TEST_F(Cli, MaxMemoryRefusesEveryMethodBeforeTheStepThatWouldNotFit) {
  for (const auto& [method, expected] : std::vector<std::pair<std::string, std::string>>{
           {"bgkl", "bucketing a scan"},
           {"bgk", "bgk's training points (scan 1"},
           {"counting", "the map's cells"},
           {"octomap", "octomap's ray update (scan 1"},
           {"gpoctomap", "gpoctomap's training points (scan 1"},
           {"gpom", "gpom's training points (scan 1"},
           {"wgpom", "gpom's training points (scan 1"},
           {"bhm", "bhm's training points (scan 1"}}) {
    const bool tree_only = method != "bgkl" && method != "bgk" && method != "counting";
    const std::string out = path(tree_only ? "m.bt" : "m.bgk");
    const Result r = run("build -q " + path("scans") + " -o " + out + " --backend cpu --method " + method +
                         " --max-memory 1M");
    EXPECT_EQ(r.status, 1) << method;
    EXPECT_EQ(r.output.find("bgkmap: error: " + expected), 0u) << method << ": " << r.output;
    EXPECT_NE(r.output.find("beyond --max-memory 1.0 MiB: give "), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_FALSE(std::filesystem::exists(out)) << method;
  }
  const Result bad = run("build -q " + path("scans") + " -o " + path("m.bgk") + " --max-memory 12X");
  EXPECT_EQ(bad.status, 1);
  EXPECT_NE(bad.output.find("'12X' is not a memory size"), std::string::npos) << bad.output;
}

// gpoctomap's dense GP per block grew to 24 GB and was killed: free points crowd the blocks
// near the sensor. A block of tens of thousands of training points is refused before its GP,
// naming --ds; the same scan with --ds fits.
TEST_F(Cli, GpoctomapRefusesABlockWhoseGpWouldNotFitNamingDs) {
  Scan scan = testing::random_scans(5, 1, 1, 1.0f)[0];
  scan.points.clear();
  scan.pose.position = {0, 0, 0};
  scan.points_in_world_frame = true;
  for (int i = 0; i < 3000; ++i)  // a wall 3 m away: 30 free points along each beam, crowding the sensor
    scan.points.push_back({3.0f, -1.0f + 0.002f * float(i % 1000), 0.1f * float(i / 1000)});
  std::filesystem::create_directories(dir_ / "wall");
  write_pcd(dir_ / "wall" / "s.pcd", scan);
  Result r = run("build -q " + path("wall") + " -o " + path("g.bt") + " --backend cpu --method gpoctomap --max-memory 1G");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_EQ(r.output.find("bgkmap: error: gpoctomap's GP per block (the largest of "), 0u) << r.output;
  EXPECT_NE(r.output.find("beyond --max-memory 1.0 GiB: give --ds"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(path("g.bt")));
  r = run("build -q " + path("wall") + " -o " + path("g.bt") + " --backend cpu --method gpoctomap --max-memory 1G --ds 0.2");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(std::filesystem::exists(path("g.bt")));
}

// bhm's update holds, per training point, every support its features reach (about 70 at the
// defaults in 3-D): it went past --max-memory unchecked (1.0 GB against a 0.95 GB limit on three
// structured scans). A wall 6 m away gives 177,000 free samples, a few MB of points but about
// 150 MB of update: refused under 120 MB naming bhm's update; under 1 GB built within the limit.
TEST_F(Cli, BhmRefusesAnUpdateThatWouldNotFit) {
  Scan scan = testing::random_scans(5, 1, 1, 1.0f)[0];
  scan.points.clear();
  scan.pose.position = {0, 0, 0};
  scan.points_in_world_frame = true;
  for (int i = 0; i < 3000; ++i) scan.points.push_back({6.0f, -1.0f + 0.002f * float(i % 1000), 0.1f * float(i / 1000)});
  std::filesystem::create_directories(dir_ / "wall");
  write_pcd(dir_ / "wall" / "s.pcd", scan);
  // The limits sit above what a tiny build takes (the process itself: more under sanitizers).
  Result r = run("build -q " + path("scans") + " -o " + path("base.bt") + " --method bhm --threads 2 --report " +
                 path("base.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  const int base_mb = static_cast<int>(report("base.json")["peak_rss_mb"].get<double>()) + 1;
  const std::string small = std::to_string(base_mb + 60) + "M", large = std::to_string(base_mb + 1024) + "M";
  r = run("build -q " + path("wall") + " -o " + path("b.bt") + " --method bhm --threads 2 --max-memory " + small);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_EQ(r.output.find("bgkmap: error: bhm's update (scan 1: 180000 training points reaching "), 0u) << r.output;
  EXPECT_NE(r.output.find(" MiB: give a larger --free-resolution"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(path("b.bt")));
  // Choosing gamma by the evidence: a smaller candidate reaches farther and needs more (270 MB
  // for the 20,000 points a candidate learns of this scan).
  r = run("build -q " + path("wall") + " -o " + path("b.bt") + " --method bhm --threads 2 --bhm-gamma 0 --max-memory " + small);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_EQ(r.output.find("bgkmap: error: bhm's choice of gamma (gamma "), 0u) << r.output;
  EXPECT_NE(r.output.find(" MiB: give --bhm-gamma"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(path("b.bt")));
  r = run("build -q " + path("wall") + " -o " + path("b.bt") + " --method bhm --threads 2 --max-memory " + large +
          " --report " + path("b.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_LT(report("b.json")["peak_rss_mb"].get<double>(), base_mb + 1024.0);
}

// render and station-keeping at coordinates the keys cannot hold (query: above).
TEST_F(Cli, RenderRefusesASliceBeyondTheKeyRange) {
  ASSERT_EQ(run("build -q " + path("scans") + " -o " + path("m.bgk") + " --backend cpu").status, 0);
  const Result r = run("render " + path("m.bgk") + " -o " + path("m.png") + " --z 1e30");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("the slice at z = 1e+30 m lies beyond the map's key range"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(path("m.png")));
}

TEST_F(Cli, QueryRejectsMalformedLinesWithTheLineNumber) {
  ASSERT_EQ(run("build -q " + path("scans") + " -o " + path("m.bgk") + " --backend cpu").status, 0);
  {
    std::ofstream q(dir_ / "q.txt");
    q << "# comment\n0 0 0\n1 2\n";
  }
  const Result r = run("query " + path("m.bgk") + " --points " + path("q.txt"));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("line 3"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace bgkmap
