// `mpirun -np K bgkmap build` against the single-process build: the merged .bgk (and .ot) must
// be the same bytes for K = 1..4, on the CPU path and on OpenCL (PoCL here), on sim_structured
// and on simulated campus scans; `bgkmap merge` of the shards too. A bad scan ends the job with
// a line naming the rank and the scan.
#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <ostream>
#include <string>

#include "bgkmap/dist/shards.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

const std::string kCli = BGKMAP_CLI;
// Containers often refuse the cross-process memory copies Open MPI's shared-memory transport uses
// for large messages; the plain copy works everywhere.
const std::string kMpirun = "env OMPI_MCA_btl_vader_single_copy_mechanism=none " + std::string(BGKMAP_MPIEXEC) +
                            " --oversubscribe --allow-run-as-root";

testing::CommandResult run(const std::string& command) { return testing::run_command(command + " 2>&1"); }

struct Case {
  std::string name;
  std::string backend;
};
// gtest names the failing case by it (else a dump of its bytes).
void PrintTo(const Case& c, std::ostream* out) { *out << c.name << " on " << c.backend; }

class MpiBuild : public ::testing::TestWithParam<Case> {};

// The scans and build flags of a case, in `dir`.
std::string inputs_and_flags(const std::string& name, const std::filesystem::path& datasets,
                             const std::filesystem::path& dir) {
  if (name == "sim_structured")
    return (datasets / "sim_structured").string() + " --resolution 0.1 --max-range 8";
  const testing::CommandResult sim =
      run(kCli + " simulate campus -q --scans 4 --truth-resolution 0 -o " + (dir / "campus").string());
  EXPECT_EQ(sim.status, 0) << sim.output;
  return (dir / "campus" / "scans").string() + " --resolution 0.2 --ell 0.6 --ds 0.5 --max-range 20";
}

// query, info and eval give on a shard folder what they give on the single-process map.
// `truth`: a truth .bt for eval at the maps' resolution, or empty.
void expect_shards_read_as_the_map(const std::string& shards, const std::string& single,
                                   const std::filesystem::path& dir, const std::filesystem::path& truth) {
  const testing::CommandResult info_single = run(kCli + " info --json " + single);
  ASSERT_EQ(info_single.status, 0) << info_single.output;
  const nlohmann::json bounds = nlohmann::json::parse(info_single.output).at("evidence_cell_centre_bounds");
  std::string points;  // a lattice over the mapped box
  for (int i = 0; i < 25; ++i)
    for (int j = 0; j < 25; ++j)
      for (int k = 0; k < 3; ++k) {
        double p[3];
        const int step[3] = {i, j, k}, steps[3] = {25, 25, 3};
        for (int a = 0; a < 3; ++a) {
          const double lo = bounds["min"][a].get<double>(), hi = bounds["max"][a].get<double>();
          p[a] = lo + (hi - lo) * (step[a] + 0.37) / steps[a];
        }
        points += std::to_string(p[0]) + " " + std::to_string(p[1]) + " " + std::to_string(p[2]) + "\n";
      }
  testing::write_bytes(dir / "points.txt", points);
  const std::string query = " --points " + (dir / "points.txt").string();
  const testing::CommandResult from_single = run(kCli + " query " + single + query);
  const testing::CommandResult from_shards = run(kCli + " query " + shards + query);
  ASSERT_EQ(from_shards.status, 0) << from_shards.output;
  EXPECT_EQ(std::count(from_shards.output.begin(), from_shards.output.end(), '\n'), 25 * 25 * 3);
  EXPECT_EQ(from_shards.output, from_single.output);
  EXPECT_NE(from_single.output.find(" free"), std::string::npos);  // the points reach mapped cells
  const testing::CommandResult info_shards = run(kCli + " info --json " + shards);
  ASSERT_EQ(info_shards.status, 0) << info_shards.output;
  EXPECT_EQ(info_shards.output, info_single.output);
  if (truth.empty()) return;
  for (const std::string& map : {single, shards}) {
    const testing::CommandResult e = run(kCli + " eval " + map + " --truth " + truth.string() + " --json " +
                                         (dir / (std::filesystem::path(map).filename().string() + ".json")).string());
    ASSERT_EQ(e.status, 0) << e.output;
  }
  nlohmann::json a = nlohmann::json::parse(testing::read_bytes(dir / (std::filesystem::path(single).filename().string() + ".json")));
  nlohmann::json b = nlohmann::json::parse(testing::read_bytes(dir / (std::filesystem::path(shards).filename().string() + ".json")));
  a.erase("map"), b.erase("map"), a.erase("maps"), b.erase("maps");
  EXPECT_GT(a.at("auc").get<double>(), 0.5);
  EXPECT_EQ(a.dump(), b.dump());
}

TEST_P(MpiBuild, MergedMapIsTheSingleProcessMapForOneToFourRanks) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  const Case c = GetParam();
  const std::filesystem::path dir = testing::make_temp_dir("mpi_build_" + c.name + "_" + c.backend);
  const std::string flags = inputs_and_flags(c.name, datasets, dir) + " -q --threads 1 --backend " + c.backend;
  const std::string single = (dir / "single.bgk").string();
  const bool octree = c.name == "sim_structured";  // the .ot of the campus scans takes long to write
  testing::CommandResult r =
      run(kCli + " build " + flags + " -o " + single + (octree ? " -o " + (dir / "single.ot").string() : ""));
  ASSERT_EQ(r.status, 0) << r.output;
  const std::string expected = testing::read_bytes(single);
  ASSERT_GT(expected.size(), 10000u);
  for (int ranks = 1; ranks <= 4; ++ranks) {
    const std::string k = (dir / ("k" + std::to_string(ranks))).string();
    r = run(kMpirun + " -np " + std::to_string(ranks) + " " + kCli + " build " + flags + " -o " + k + ".bgk" +
            (octree ? " -o " + k + ".ot" : "") + " --shards " + k + ".shards");
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_TRUE(testing::read_bytes(k + ".bgk") == expected) << ranks << " ranks: the .bgk differs";
    if (octree) {
      EXPECT_TRUE(testing::read_bytes(k + ".ot") == testing::read_bytes(dir / "single.ot")) << ranks << " ranks: .ot";
    }
    if (ranks == 3) {  // the shards merged again by the command, and read as they are
      r = run(kCli + " merge " + k + ".shards -o " + k + "-merged.bgk");
      ASSERT_EQ(r.status, 0) << r.output;
      EXPECT_TRUE(testing::read_bytes(k + "-merged.bgk") == expected) << "bgkmap merge";
      // Written into the folder it reads, the merged map could replace a shard (it did: rank-0000.bgk).
      const std::string shard0 = k + ".shards/" + shard_map_name(0);
      const std::string before = testing::read_bytes(shard0);
      r = run(kCli + " merge " + k + ".shards -o " + shard0);
      EXPECT_NE(r.status, 0);
      EXPECT_NE(r.output.find("inside the shard folder"), std::string::npos) << r.output;
      EXPECT_TRUE(testing::read_bytes(shard0) == before);
      // eval against sim_structured's OctoMap reference (a stand-in truth: the same scores either way).
      expect_shards_read_as_the_map(k + ".shards", single, dir,
                                    octree ? datasets / "sim_structured" / "octomap_reference.bt" : "");
    }
  }
  std::filesystem::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Cases, MpiBuild,
                         ::testing::Values(Case{"sim_structured", "cpu"}, Case{"sim_structured", "opencl"},
                                           Case{"campus", "cpu"}, Case{"campus", "opencl"}),
                         [](const auto& p) { return p.param.name + "_" + p.param.backend; });

TEST(MpiBuildFaults, ABadScanEndsTheJobNamingTheRankAndTheScan) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  const std::filesystem::path dir = testing::make_temp_dir("mpi_build_bad");
  for (int i = 1; i <= 5; ++i) {
    const std::string name = "scan_0" + std::to_string(i) + ".pcd";
    std::filesystem::copy_file(datasets / "sim_structured" / name, dir / name);
  }
  testing::write_bytes(dir / "scan_06.pcd", "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nnot a pcd\n");
  const testing::CommandResult r =
      run(kMpirun + " -np 2 " + kCli + " build -q --threads 1 --backend cpu " + dir.string() + " -o " +
          (dir / "m.bgk").string());
  EXPECT_NE(r.status, 0);
  // Scan 5 (the sixth) is rank 1's (5 % 2), found bad while reading for the partition.
  EXPECT_NE(r.output.find("bgkmap: rank 1: scan 5: " + (dir / "scan_06.pcd").string() + ": "), std::string::npos)
      << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "m.bgk"));
  std::filesystem::remove_all(dir);
}

TEST(MpiBuildFaults, ForgettingIsRefusedBeforeWork) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  const std::filesystem::path dir = testing::make_temp_dir("mpi_build_forget");
  const testing::CommandResult r = run(kMpirun + " -np 2 " + kCli + " build -q --threads 1 --backend cpu " +
                                       (datasets / "sim_structured").string() + " --forget-half-life 3 -o " +
                                       (dir / "m.bgk").string());
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("bgkmap: error: --forget-half-life is for a single-process build\n"), std::string::npos)
      << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "m.bgk"));
  std::filesystem::remove_all(dir);
}

// sim_structured as the checkpoint tests build it (one thread a rank, the CPU back end).
std::string sim_structured_flags(const std::filesystem::path& datasets) {
  return (datasets / "sim_structured").string() + " --resolution 0.1 --max-range 8 -q --threads 1 --backend cpu";
}

// The single-process map of `flags`, DIR/single.bgk, that the ranks' maps must equal.
testing::CommandResult build_single_process_map(const std::string& flags, const std::filesystem::path& dir) {
  return run(kCli + " build " + flags + " -o " + (dir / "single.bgk").string());
}

TEST(MpiBuildFaults, ARankKilledMidBuildIsResumedFromTheLastCheckpointToTheSameMap) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  const std::filesystem::path dir = testing::make_temp_dir("mpi_build_kill");
  const std::string flags = sim_structured_flags(datasets);
  testing::CommandResult r = build_single_process_map(flags, dir);
  ASSERT_EQ(r.status, 0) << r.output;
  const std::string build = kCli + " build " + flags + " --checkpoint-every 2 --shards " + (dir / "s").string() +
                            " -o " + (dir / "k.bgk").string();
  // Rank 1 dies (SIGKILL, as a lost node) as it is about to map scan 7. Its checkpoint of 6 scans
  // is written; rank 0 maps up to 8 rounds behind, so the last complete checkpoint (both shards and
  // the manifest) is of 6 scans or, when rank 0 lags, of 4 or 2. mpirun names the rank; rank 0,
  // ended by mpirun, prints each rank's last step.
  r = run("env BGKMAP_KILL_RANK_AT=1:7 " + kMpirun + " -np 2 " + build);
  EXPECT_NE(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("rank 1 "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("rank 1: mapping scan 7"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "k.bgk"));
  ASSERT_TRUE(std::filesystem::exists(dir / "s" / "manifest.json")) << r.output;
  const int held = nlohmann::json::parse(testing::read_bytes(dir / "s" / "manifest.json"))["scans"].get<int>();
  EXPECT_TRUE(held == 2 || held == 4 || held == 6) << held;
  // The checkpoint is a map a single process continues too: merged, it records the scans it holds.
  r = run(kCli + " merge " + (dir / "s").string() + " -o " + (dir / "at.bgk").string());
  ASSERT_EQ(r.status, 0) << r.output;
  r = run(kCli + " build " + flags + " --resume " + (dir / "at.bgk").string() + " -o " + (dir / "one.bgk").string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("holds " + std::to_string(held) + " scans of these inputs already"), std::string::npos)
      << r.output;
  EXPECT_TRUE(testing::read_bytes(dir / "one.bgk") == testing::read_bytes(dir / "single.bgk"));
  // A resume refused for its flags leaves the interrupted run's steps to the next one.
  r = run(kMpirun + " -np 2 " + build + " --resume " + (dir / "s").string() + " --ell 0.5");
  EXPECT_NE(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("other parameters"), std::string::npos) << r.output;
  // The same command with --resume continues from the checkpoint to the same bytes.
  r = run(kMpirun + " -np 2 " + build + " --resume " + (dir / "s").string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("  rank 1: mapping scan 7"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("resuming from the checkpoint of " + std::to_string(held) + " scans"), std::string::npos)
      << r.output;
  EXPECT_TRUE(testing::read_bytes(dir / "k.bgk") == testing::read_bytes(dir / "single.bgk"));
  // Only the final shards are left.
  size_t files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir / "s")) files += entry.is_regular_file();
  EXPECT_EQ(files, 5u);  // two shards of two files each, and the manifest
  // A rank ended by a signal it can catch names itself and its scan.
  r = run("env BGKMAP_KILL_RANK_AT=0:4:15 " + kMpirun + " -np 2 " + kCli + " build " + flags + " -o " +
          (dir / "t.bgk").string());
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("bgkmap: rank 0 ended by signal 15 while mapping scan 4"), std::string::npos) << r.output;
  std::filesystem::remove_all(dir);
}

// A rank killed before the first checkpoint leaves the progress file and no manifest: --resume of
// that folder begins again from the first scan (as a single-process --resume of a checkpoint not
// yet written does), and so does the same command run again; a folder of neither is refused.
TEST(MpiBuildFaults, ARankKilledBeforeTheFirstCheckpointIsResumedFromTheFirstScan) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  const std::filesystem::path dir = testing::make_temp_dir("mpi_build_kill_early");
  const std::string flags = sim_structured_flags(datasets);
  testing::CommandResult r = build_single_process_map(flags, dir);
  ASSERT_EQ(r.status, 0) << r.output;
  const std::string shards = (dir / "s").string();
  const std::string build =
      kMpirun + " -np 2 " + kCli + " build " + flags + " --checkpoint-every 4 --shards " + shards + " -o " + (dir / "k.bgk").string();
  for (const bool resume : {true, false}) {
    r = run("env BGKMAP_KILL_RANK_AT=1:1 " + build);  // rank 1's first scan: no checkpoint yet
    EXPECT_NE(r.status, 0) << r.output;
    ASSERT_FALSE(std::filesystem::exists(dir / "s" / "manifest.json")) << r.output;
    ASSERT_TRUE(std::filesystem::exists(dir / "s" / "progress")) << r.output;
    r = run(build + (resume ? " --resume " + shards : ""));
    ASSERT_EQ(r.status, 0) << (resume ? "--resume: " : "rerun: ") << r.output;
    if (resume) {
      EXPECT_NE(r.output.find("bgkmap: no checkpoint in " + shards + " yet (the interrupted run wrote none): building "
                              "from the first scan"), std::string::npos) << r.output;
      EXPECT_NE(r.output.find("  rank 1: mapping scan 1"), std::string::npos) << r.output;  // the interrupted run's step
      EXPECT_FALSE(std::filesystem::exists(dir / "s" / "progress.interrupted"));
    }
    EXPECT_TRUE(testing::read_bytes(dir / "k.bgk") == testing::read_bytes(dir / "single.bgk")) << resume;
    std::filesystem::remove_all(dir / "s");
    std::filesystem::remove(dir / "k.bgk");
  }
  std::filesystem::create_directories(dir / "empty");
  r = run(kMpirun + " -np 2 " + kCli + " build " + flags + " -o " + (dir / "k.bgk").string() + " --resume " +
          (dir / "empty").string());
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("bgkmap: rank 0: " + (dir / "empty").string() + ": holds no checkpoint (no manifest.json) and "
                          "no interrupted run's progress file: give the shard folder of the interrupted run, or build "
                          "without --resume\n"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "k.bgk"));
  std::filesystem::remove_all(dir);
}

// Without --shards the ranks write the .bgk together, keep no final shards, and remove the
// default shard folder with its checkpoints at the end: the single-process bytes, no folder left.
TEST(MpiBuildOutputs, WithoutShardsTheCheckpointFolderIsRemovedAndTheMapIsTheSingleProcessMap) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  const std::filesystem::path dir = testing::make_temp_dir("mpi_build_noshards");
  const std::string flags = sim_structured_flags(datasets);
  testing::CommandResult r = build_single_process_map(flags, dir);
  ASSERT_EQ(r.status, 0) << r.output;
  r = run(kMpirun + " -np 2 " + kCli + " build " + flags + " --checkpoint-every 2 -o " + (dir / "k.bgk").string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(testing::read_bytes(dir / "k.bgk") == testing::read_bytes(dir / "single.bgk"));
  EXPECT_FALSE(std::filesystem::exists(dir / "k.bgk.shards"));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap
