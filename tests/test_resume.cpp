// Crash safety of `bgkmap build`: checkpoints, --resume passing over the scans a map holds, and a
// real build killed with SIGKILL at random moments and resumed, again and again, ending with the
// same bytes as a build never interrupted.
#include <gtest/gtest.h>
#include <fcntl.h>
#include <octomap/ScanGraph.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "bgkmap/io/map_io.hpp"
#include "bgkmap/io/pcd_io.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

namespace fs = std::filesystem;
using Result = testing::CommandResult;

Result run(const std::string& args) { return testing::run_command(std::string(BGKMAP_CLI) + " " + args); }

// Starts bgkmap with these arguments (output to /dev/null) and returns its process id.
pid_t spawn(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  std::string cli = BGKMAP_CLI;
  argv.push_back(cli.data());
  std::vector<std::string> copy = args;
  for (std::string& a : copy) argv.push_back(a.data());
  argv.push_back(nullptr);
  const pid_t pid = fork();
  if (pid == 0) {
    const int null = open("/dev/null", O_WRONLY);
    dup2(null, 1);
    dup2(null, 2);
    execv(argv[0], argv.data());
    _exit(127);
  }
  return pid;
}

// Waits for it; true when it exited 0, false when the signal ended it first.
bool finished(pid_t pid) {
  int status = 0;
  waitpid(pid, &status, 0);
  if (WIFEXITED(status)) {
    EXPECT_EQ(WEXITSTATUS(status), 0);
    return true;
  }
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << status;
  return false;
}

std::vector<std::string> split(const std::string& s) {
  std::istringstream in(s);
  std::vector<std::string> out;
  for (std::string w; in >> w;) out.push_back(w);
  return out;
}

class Resume : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::make_temp_dir("resume");
    fs::create_directories(dir_ / "scans");
    const auto scans = testing::random_scans(7, 21, 600, 1.5f);
    for (int i = 0; i < 16; ++i) write_pcd(dir_ / "scans" / ("s_" + std::to_string(i + 1) + ".pcd"), scans[i]);
    // After them a scan graph of five nodes: a checkpoint may fall inside it.
    octomap::ScanGraph graph;
    for (int i = 16; i < 21; ++i) {
      auto* cloud = new octomap::Pointcloud();  // the graph owns it
      for (const Vec3f& p : scans[i].points)
        cloud->push_back(p.x - scans[i].pose.position.x, p.y - scans[i].pose.position.y, p.z - scans[i].pose.position.z);
      graph.addNode(cloud, octomap::pose6d(scans[i].pose.position.x, scans[i].pose.position.y, scans[i].pose.position.z,
                                           0, 0, 0));
    }
    ASSERT_TRUE(graph.writeBinary((dir_ / "scans" / "s_17.graph").string()));
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  nlohmann::json report(const std::string& name) const {
    std::ifstream in(dir_ / name);
    return nlohmann::json::parse(in);
  }
  std::vector<std::string> temporaries() const {
    std::vector<std::string> found;
    for (const auto& e : fs::recursive_directory_iterator(dir_))
      if (e.path().filename().string().find(".tmp-") != std::string::npos) found.push_back(e.path().string());
    return found;
  }
  const std::string flags_ = " --backend cpu --threads 2 --max-range 2.5 --resolution 0.1";
  fs::path dir_;
};

TEST_F(Resume, ResumingPassesOverTheHeldScansSaysSoOnceAndGivesTheSameBytes) {
  ASSERT_EQ(run("build -q " + path("scans") + " -o " + path("all.bgk") + flags_).status, 0);
  const NativeMapFile all = read_native_map_file(path("all.bgk"));
  ASSERT_EQ(all.held.size(), 17u);
  EXPECT_EQ(all.held[0].path, path("scans/s_1.pcd"));
  EXPECT_EQ(all.held[0].scans, 1u);
  EXPECT_EQ(all.held[0].sha256, sha256_of_file(path("scans/s_1.pcd")));
  EXPECT_EQ(all.held[16].path, path("scans/s_17.graph"));
  EXPECT_EQ(all.held[16].scans, 5u);  // every node
  EXPECT_EQ(all.held[16].sha256, sha256_of_file(path("scans/s_17.graph")));

  const Result info = run("info --json " + path("all.bgk"));
  ASSERT_EQ(info.status, 0) << info.output;
  EXPECT_EQ(nlohmann::json::parse(info.output)["format_version"].get<int>(), 3);
  EXPECT_EQ(nlohmann::json::parse(info.output)["held_inputs"].size(), 17u);

  // Two of the files, then all of them resumed: only the rest is added.
  ASSERT_EQ(run("build -q " + path("scans/s_1.pcd") + " " + path("scans/s_2.pcd") + " -o " + path("part.bgk") + flags_).status, 0);
  const Result r = run("build -q " + path("scans") + " --resume " + path("part.bgk") + " -o " + path("resumed.bgk") +
                       " --report " + path("r.json") + flags_);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(r.output, "bgkmap: " + path("part.bgk") + " holds 2 scans of these inputs already: skipping them\n");
  EXPECT_EQ(report("r.json")["counts"]["scans_already_held"].get<int>(), 2);
  EXPECT_EQ(report("r.json")["counts"]["scans"].get<int>(), 19);
  EXPECT_EQ(report("r.json")["resumed_from"], path("part.bgk"));
  EXPECT_EQ(testing::read_bytes(path("resumed.bgk")), testing::read_bytes(path("all.bgk")));

  // A map that holds everything adds nothing.
  const Result again = run("build -q " + path("scans") + " --resume " + path("all.bgk") + " -o " + path("again.bgk") + flags_);
  EXPECT_EQ(again.output, "bgkmap: " + path("all.bgk") + " holds 21 scans of these inputs already: skipping them\n");
  EXPECT_EQ(testing::read_bytes(path("again.bgk")), testing::read_bytes(path("all.bgk")));
}

// With forgetting each block keeps its own time in the .bgk: a build resumed halfway, or from a
// checkpoint, writes the uninterrupted build's bytes (the .bgk and the decayed .ot); a resume that
// changes the half-life is refused.
TEST_F(Resume, WithForgettingResumingGivesTheUninterruptedBytes) {
  const std::string forget = flags_ + " --forget-half-life 3";
  ASSERT_EQ(run("build -q " + path("scans") + " -o " + path("all.bgk") + " -o " + path("all.ot") + forget).status, 0);
  ASSERT_EQ(run("build -q " + path("scans") + " -o " + path("kept.bgk") + flags_).status, 0);
  EXPECT_NE(testing::read_bytes(path("all.bgk")), testing::read_bytes(path("kept.bgk")));
  std::string half;
  for (int i = 1; i <= 8; ++i) half += " " + path("scans/s_" + std::to_string(i) + ".pcd");
  ASSERT_EQ(run("build -q" + half + " -o " + path("half.bgk") + forget).status, 0);
  const Result r = run("build -q " + path("scans") + " --resume " + path("half.bgk") + " -o " + path("resumed.bgk") +
                       " -o " + path("resumed.ot") + forget);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(testing::read_bytes(path("resumed.bgk")), testing::read_bytes(path("all.bgk")));
  EXPECT_EQ(testing::read_bytes(path("resumed.ot")), testing::read_bytes(path("all.ot")));

  // Checkpoints every 5 scans: the one of scan 20 resumed gives the same bytes again.
  ASSERT_EQ(run("build -q " + path("scans") + " -o " + path("ck.bgk") + " --checkpoint-every 5 --checkpoint " +
                path("ck20.bgk") + forget).status, 0);
  EXPECT_EQ(testing::read_bytes(path("ck.bgk")), testing::read_bytes(path("all.bgk")));
  ASSERT_EQ(run("build -q " + path("scans") + " --resume " + path("ck20.bgk") + " -o " + path("from20.bgk") + forget).status, 0);
  EXPECT_EQ(testing::read_bytes(path("from20.bgk")), testing::read_bytes(path("all.bgk")));

  const Result changed = run("build -q " + path("scans") + " --resume " + path("half.bgk") + " -o " + path("x.bgk") +
                             flags_ + " --forget-half-life 4");
  EXPECT_EQ(changed.status, 1) << changed.output;
  EXPECT_EQ(changed.output, "bgkmap: error: cannot change 'forget-half-life' when resuming a map (stored 3.0, asked "
                            "4.0): give the build's --forget-half-life again\n");
}

// The last checkpoint of a build with --checkpoint-every 6 falls after the graph's second node
// (scans 6, 12 and 18 of 16 .pcd files and 5 nodes): resuming from it reads the graph, passes
// over two nodes and adds the other three.
TEST_F(Resume, ACheckpointInsideAGraphHoldsItsFirstNodes) {
  ASSERT_EQ(run("build -q " + path("scans") + " -o " + path("all.bgk") + " -o " + path("all.ot") + flags_).status, 0);
  const Result r = run("build -q " + path("scans") + " -o " + path("m.bgk") + " --checkpoint-every 6 --checkpoint " +
                       path("c.bgk") + " --report " + path("r.json") + flags_);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(report("r.json")["checkpoint"]["written"].get<int>(), 3);
  EXPECT_EQ(report("r.json")["checkpoint"]["path"], path("c.bgk"));
  EXPECT_EQ(testing::read_bytes(path("m.bgk")), testing::read_bytes(path("all.bgk")));  // checkpoints change nothing
  const NativeMapFile checkpoint = read_native_map_file(path("c.bgk"));
  ASSERT_EQ(checkpoint.held.size(), 17u);
  EXPECT_EQ(checkpoint.held[16].scans, 2u);

  // Resumed with 8 threads: one of them reads ahead, so the scans' origins cross threads.
  std::string flags8 = flags_;
  flags8.replace(flags8.find("--threads 2"), 11, "--threads 8");
  const Result resumed = run("build -q " + path("scans") + " --resume " + path("c.bgk") + " -o " + path("r.bgk") + " -o " +
                             path("r.ot") + " --report " + path("r2.json") + flags8);
  ASSERT_EQ(resumed.status, 0) << resumed.output;
  EXPECT_EQ(report("r2.json")["counts"]["scans_already_held"].get<int>(), 18);
  EXPECT_EQ(report("r2.json")["counts"]["scans"].get<int>(), 3);
  EXPECT_EQ(testing::read_bytes(path("r.bgk")), testing::read_bytes(path("all.bgk")));
  EXPECT_EQ(testing::read_bytes(path("r.ot")), testing::read_bytes(path("all.ot")));
}

TEST_F(Resume, AChangedInputIsNotHeldAndParametersStayFixed) {
  ASSERT_EQ(run("build -q " + path("scans") + " -o " + path("all.bgk") + flags_).status, 0);
  write_pcd(dir_ / "scans" / "s_2.pcd", testing::random_scans(99, 1, 300, 1.5f)[0]);  // new contents, same name
  const Result r = run("build -q " + path("scans") + " --resume " + path("all.bgk") + " -o " + path("m.bgk") + " --report " +
                       path("r.json") + flags_);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(report("r.json")["counts"]["scans_already_held"].get<int>(), 20);
  EXPECT_EQ(report("r.json")["counts"]["scans"].get<int>(), 1);
  EXPECT_EQ(read_native_map_file(path("m.bgk")).held.size(), 18u);  // both versions of s_2.pcd

  const Result refused = run("build -q " + path("scans") + " --resume " + path("all.bgk") + " -o " + path("x.bgk") + flags_ +
                             " --ell 0.3");
  EXPECT_EQ(refused.status, 1);
  EXPECT_NE(refused.output.find("cannot change 'ell' when resuming a map"), std::string::npos) << refused.output;
}

TEST_F(Resume, CheckpointAndResumeFlagsAreCheckedBeforeWork) {
  const auto refused = [&](const std::string& args, const std::string& expected) {
    const Result r = run("build -q " + path("scans") + " " + args + flags_);
    EXPECT_EQ(r.status, 1) << args;
    EXPECT_NE(r.output.find(expected), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  };
  refused("-o " + path("m.ot") + " --checkpoint-every 2", "--checkpoint-every needs a .bgk output");
  refused("-o " + path("m.ot") + " --checkpoint-every 2 --method octomap", "cannot be used with --method octomap");
  refused("-o " + path("m.bgk") + " --checkpoint " + path("c.bgk"), "--checkpoint needs --checkpoint-every N");
  const Result ot = run("build -q " + path("scans") + " -o " + path("m.bgk") + " --checkpoint-every 2 --checkpoint " +
                        path("c.ot") + flags_);
  EXPECT_EQ(ot.status, 2) << ot.output;  // a usage error, refused at parse
  EXPECT_NE(ot.output.find("--checkpoint: " + path("c.ot") + ": a checkpoint is a native .bgk map"), std::string::npos)
      << ot.output;
  refused("-o " + path("m.bgk") + " --checkpoint-every 2 --checkpoint " + path("missing/c.bgk"),
          path("missing/c.bgk") + ": cannot write into folder");
  refused("-o " + path("m.bgk") + " --resume " + path("none.bgk"), path("none.bgk") + ": no such file");
  EXPECT_FALSE(fs::exists(dir_ / "m.bgk"));
  const Result negative = run("build -q " + path("scans") + " -o " + path("m.bgk") + " --checkpoint-every -1" + flags_);
  EXPECT_NE(negative.status, 0);  // was taken as 2^64 - 1: no checkpoint ever, silently
  EXPECT_NE(negative.output.find("--checkpoint-every: '-1' is not a count of scans"), std::string::npos) << negative.output;
  EXPECT_FALSE(fs::exists(dir_ / "m.bgk"));

  // A --resume path that is the checkpoint and does not exist yet: a build killed before its first checkpoint.
  const Result fresh = run("build -q " + path("scans") + " -o " + path("m.bgk") + " --checkpoint-every 2 --resume " +
                           path("m.bgk") + flags_);
  ASSERT_EQ(fresh.status, 0) << fresh.output;
  EXPECT_EQ(fresh.output, "bgkmap: no checkpoint at " + path("m.bgk") + " yet: building from the first scan\n");
}

// kill -9 at random moments (start-up, mapping, a checkpoint being written, the outputs being
// committed), then the same command with --resume, killed again at random, until a run finishes
// before its kill: the map is the uninterrupted one byte for byte, and no temporary is left.
// Kill moments scale with the uninterrupted run's measured duration T, so a fast machine and a
// loaded one both see interrupted runs: each trial's first kill falls in [0, T/2), later ones in
// [0, 1.5 T), so a trial kills runs until one finishes.
TEST_F(Resume, BuildsKilledAtRandomMomentsResumeToTheUninterruptedBytes) {
  const std::string outputs = " -o " + path("m.bgk") + " -o " + path("m.ot");
  const auto started = std::chrono::steady_clock::now();
  ASSERT_EQ(run("build -q " + path("scans") + " -o " + path("ref.bgk") + " -o " + path("ref.ot") + flags_).status, 0);
  const double uninterrupted_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  const std::vector<std::string> command = split("build -q " + path("scans") + outputs + " --checkpoint-every 1" + flags_);
  std::vector<std::string> resume = command;
  resume.push_back("--resume");
  resume.push_back(path("m.bgk"));

  const unsigned seed = std::random_device{}();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> fraction(0.0, 1.0);
  int kills = 0, interrupted = 0;
  for (int trial = 0; trial < 3; ++trial) {
    SCOPED_TRACE("seed " + std::to_string(seed) + ", trial " + std::to_string(trial));
    fs::remove(dir_ / "m.bgk");
    fs::remove(dir_ / "m.ot");
    for (int attempt = 0; attempt < 15; ++attempt) {
      const pid_t pid = spawn(attempt == 0 ? command : resume);
      const double latest_s = (attempt == 0 ? 0.5 : 1.5) * uninterrupted_s;
      std::this_thread::sleep_for(std::chrono::duration<double>(fraction(rng) * latest_s));
      kill(pid, SIGKILL);
      ++kills;
      if (finished(pid)) break;
      ++interrupted;
    }
    const Result last = run("build -q " + path("scans") + outputs + " --checkpoint-every 1 --resume " + path("m.bgk") + flags_);
    ASSERT_EQ(last.status, 0) << last.output;
    ASSERT_EQ(testing::read_bytes(path("m.bgk")), testing::read_bytes(path("ref.bgk")));
    ASSERT_EQ(testing::read_bytes(path("m.ot")), testing::read_bytes(path("ref.ot")));
    EXPECT_EQ(temporaries(), std::vector<std::string>{});
  }
  std::printf("%d of %d kills interrupted a build (seed %u, uninterrupted run %.3f s)\n", interrupted, kills, seed,
              uninterrupted_s);
  EXPECT_GT(interrupted, 0);
}

}  // namespace
}  // namespace bgkmap
