// Inputs and flags that probing found ending in a signal, undefined behaviour, a silent exit 0 or
// a lost file: each class now gives a result or a one-line refusal naming the flag or file.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "bgkmap/dist/shards.hpp"
#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/io/native_map.hpp"
#include "bgkmap/io/pcd_io.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

using testing::CommandResult;
using testing::TempDir;

CommandResult bgkmap(const std::string& args) { return testing::run_command(std::string(BGKMAP_CLI) + " " + args); }

// One PCD scan of `points` seen from `origin`.
void write_scan(const std::filesystem::path& file, Vec3f origin, const std::vector<Vec3f>& points) {
  Scan scan;
  scan.pose.position = origin;
  scan.points = points;
  write_pcd(file, scan);
}

// Exit 1 (not a signal), one line, naming `expected`.
void expect_refusal(const CommandResult& r, const std::string& expected, const std::string& what) {
  EXPECT_EQ(r.status, 1) << what << ": " << r.output;
  EXPECT_NE(r.output.find(expected), std::string::npos) << what << ": " << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << what << ": " << r.output;
}

// liboctomap writes a ray's keys into a fixed buffer unchecked: a ray whose float length is 0
// looped past it, a 6 km ray overflowed it (rc 139), a point beyond its key range was dropped
// with a warning and exit 0.
TEST(Reliability, OctomapRaysLiboctomapCannotTraceAreRefusedNotCrashed) {
  TempDir dir("reliability-octomap");
  write_scan(dir / "tiny.pcd", {0, 0, 0}, {{-1e-30f, -1e-30f, 0}});
  write_scan(dir / "long.pcd", {-3000, -3000, -3000}, {{3000, 3000, 3000}});
  write_scan(dir / "far.pcd", {0, 0, 0}, {{4000, 0, 0}});
  const std::string out = " --method octomap -o " + (dir / "m.ot").string() + " --max-range 20000";
  expect_refusal(bgkmap("build -q " + (dir / "tiny.pcd").string() + out), "too short for liboctomap to trace", "tiny");
  expect_refusal(bgkmap("build -q " + (dir / "long.pcd").string() + out), "give a shorter --max-range", "long");
  expect_refusal(bgkmap("build -q " + (dir / "far.pcd").string() + out), "give a coarser --resolution", "far");
  EXPECT_FALSE(std::filesystem::exists(dir / "m.ot"));
  // The same far ray fits the key range of coarser cells.
  const CommandResult coarse = bgkmap("build -q " + (dir / "far.pcd").string() + out + " --resolution 0.2");
  EXPECT_EQ(coarse.status, 0) << coarse.output;
  EXPECT_EQ(coarse.output.find("WARNING"), std::string::npos) << coarse.output;
}

TEST(Reliability, FlagsAndConfigValuesOutsideTheirRangesAreRefusedBeforeWork) {
  TempDir dir("reliability-ranges");
  std::filesystem::create_directories(dir / "scans");
  write_scan(dir / "scans" / "s.pcd", {0.2f, 0.1f, 0.3f}, testing::random_scans(3, 1, 200, 1.5f)[0].points);
  std::ofstream(dir / "c.yaml") << "ds: 1e-45\n";
  const int cores = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  const int too_many = std::max(64, kMaxThreadsPerCore * cores) + 1;
  const std::string build = "build -q " + (dir / "scans").string() + " -o " + (dir / "m.bgk").string() + " ";
  for (const auto& [flags, expected] : std::vector<std::pair<std::string, std::string>>{
           {"--ds 1e-30", "--ds 1e-30 m is below 0.01 of --resolution"},   // kept 2 of 3,500 points, rc 0
           {"--config " + (dir / "c.yaml").string(), "c.yaml: ds 1e-45 m is below 0.01 of resolution"},
           {"--resolution 1e308", "--resolution must be in [0.001, 10000] m"},     // NaN in the bucketing, rc 0
           {"--threads 100000", "--threads 100000 is outside"},            // libgomp overflowed its stack
           {"--threads " + std::to_string(too_many), "--threads " + std::to_string(too_many) + " is outside"}}) {
    expect_refusal(bgkmap(build + flags), expected, flags);
    EXPECT_FALSE(std::filesystem::exists(dir / "m.bgk")) << flags;
  }
  const CommandResult fine = bgkmap(build + "--ds 0.001 --threads 2 --backend cpu");
  EXPECT_EQ(fine.status, 0) << fine.output;
}

// --ell's reach is a bound for the methods that pair points with blocks by the kernel; the ray
// methods refused fine cells for it.
TEST(Reliability, RayMethodsTakeResolutionsOnlyTheKernelsReachRefuses) {
  TempDir dir("reliability-reach");
  write_scan(dir / "s.pcd", {0.2f, 0.1f, 0.3f}, testing::random_scans(4, 1, 100, 0.3f)[0].points);
  const std::string build = "build -q " + (dir / "s.pcd").string() + " --resolution 0.001 ";
  EXPECT_EQ(bgkmap(build + "--method counting -o " + (dir / "c.bgk").string()).status, 0);
  EXPECT_EQ(bgkmap(build + "--method octomap -o " + (dir / "o.ot").string()).status, 0);
  expect_refusal(bgkmap(build + "-o " + (dir / "k.bgk").string()), "--ell 0.2 m reaches 26 blocks", "bgkl");
}

// A sensor origin beyond the key range (1e6 m): its points were dropped but the origin still
// entered the scan's block window, a float-to-int overflow.
TEST(Reliability, AnOriginBeyondTheKeyRangeMapsNothingAndIsCounted) {
  TempDir dir("reliability-origin");
  write_scan(dir / "s.pcd", {2e9f, 0, 0}, {{2e9f + 1, 0, 0}, {2e9f, 1, 0}});
  const CommandResult r = bgkmap("build -q " + (dir / "s.pcd").string() + " -o " + (dir / "m.bgk").string() +
                                 " --report " + (dir / "r.json").string() + " --backend cpu");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(testing::read_bytes(dir / "r.json").find("\"dropped_out_of_key_range\": 2"), std::string::npos);
}

TEST(Reliability, OutputsNeverOverwriteEachOtherOrAnInput) {
  TempDir dir("reliability-outputs");
  write_scan(dir / "s.pcd", {0.2f, 0.1f, 0.3f}, testing::random_scans(5, 1, 200, 1.5f)[0].points);
  const std::string scan_bytes = testing::read_bytes(dir / "s.pcd");
  const std::string build = "build -q " + (dir / "s.pcd").string() + " --backend cpu ";
  const std::string map = (dir / "m.bgk").string();
  expect_refusal(bgkmap(build + "-o " + map + " --report " + map), "is the same file as -o", "-o = --report");
  expect_refusal(bgkmap(build + "-o " + map + " -o " + (dir / "." / "m.bgk").string()), "is the same file as -o", "-o twice");
  EXPECT_FALSE(std::filesystem::exists(dir / "m.bgk"));
  expect_refusal(bgkmap(build + "-o " + map + " --report " + (dir / "s.pcd").string()), "would overwrite the input",
                 "--report onto the scan");
  EXPECT_EQ(testing::read_bytes(dir / "s.pcd"), scan_bytes);
  // A link whose file does not exist yet: the file is made, the link stays.
  std::filesystem::create_symlink("real.bgk", dir / "link.bgk");
  const CommandResult linked = bgkmap(build + "-o " + (dir / "link.bgk").string());
  ASSERT_EQ(linked.status, 0) << linked.output;
  EXPECT_TRUE(std::filesystem::is_symlink(dir / "link.bgk"));
  EXPECT_TRUE(std::filesystem::is_regular_file(dir / "real.bgk"));
}

// nlohmann casts a float to an integer unchecked (undefined for 1e300), and a numeric "format"
// threw its raw type_error with no file named.
TEST(Reliability, ShardManifestCountsAndFormatAreCheckedNamingTheFile) {
  TempDir dir("reliability-manifest");
  const std::filesystem::path file = dir / "manifest.json";
  const std::string rest = R"("ranks": 1, "partition_first_codes": [0], "shards": [], "inputs": [])";
  for (const std::string& json : {std::string(R"({"format": 7, "scans": 1, )") + rest + "}",
                                  std::string(R"({"format": "bgkmap-shards", "scans": 1e300, )") + rest + "}"}) {
    testing::write_bytes(file, json);
    testing::expect_input_error(file, [&] { read_manifest(file); }, json);
  }
}

// --points read with std::getline: /dev/zero grew one line to the address-space limit, and a bad
// line of 30 MB was echoed whole in the "one-line" error.
TEST(Reliability, QueryPointsAreReadInBoundedLinesAndQuotedShort) {
  TempDir dir("reliability-query");
  write_scan(dir / "s.pcd", {0.2f, 0.1f, 0.3f}, testing::random_scans(7, 1, 100, 1.5f)[0].points);
  const std::string map = (dir / "m.bgk").string();
  ASSERT_EQ(bgkmap("build -q " + (dir / "s.pcd").string() + " -o " + map + " --backend cpu").status, 0);
  expect_refusal(bgkmap("query " + map + " --points /dev/zero"), "/dev/zero: line 1", "/dev/zero");
  expect_refusal(bgkmap("query " + map + " --points " + dir.path().string()), "is a folder", "a folder");
  testing::write_bytes(dir / "long.txt", "0 0 0\n1 " + std::string(1 << 20, 'x') + "\n");
  const CommandResult r = bgkmap("query " + map + " --points " + (dir / "long.txt").string());
  EXPECT_EQ(r.status, 1) << r.output.substr(0, 200);
  const std::string error = r.output.substr(r.output.find("bgkmap: error"));
  EXPECT_NE(error.find("line 2: expected 'x y z'"), std::string::npos) << error.substr(0, 200);
  EXPECT_LT(error.size(), 300u) << error.substr(0, 200);
}

// 545 mutated trees named their type by echoing the corrupt bytes, terminal escapes included.
TEST(Reliability, ACorruptTreeTypeIsQuotedWithoutItsControlBytes) {
  TempDir dir("reliability-tree");
  testing::write_bytes(dir / "bad.ot", "# Octomap OcTree file\nid OcT\xe9" "ee\x1b[31m\nsize 1\nres 0.1\ndata\n");
  const CommandResult r = bgkmap("render " + (dir / "bad.ot").string() + " -o " + (dir / "m.png").string());
  expect_refusal(r, "holds an OctoMap OcT?ee?[31m, not an OcTree", "tree type");
  EXPECT_EQ(r.output.find('\x1b'), std::string::npos);
}

// A file that is large but sparse (a few bytes on disk) promised 10^8 points, and the readers
// allocated for them before any estimate: 5.9 GB under --max-memory 500M.
TEST(Reliability, ReadersRefuseWhatTheirHeaderPromisesBeyondMaxMemory) {
  TempDir dir("reliability-sparse");
  constexpr uint64_t kPoints = 20'000'000;
  const std::string header = "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH " +
                             std::to_string(kPoints) + "\nHEIGHT 1\nVIEWPOINT 1 0 0 1 0 0 0\nPOINTS " +
                             std::to_string(kPoints) + "\nDATA binary\n";
  testing::write_bytes(dir / "sparse.pcd", header);
  std::filesystem::resize_file(dir / "sparse.pcd", header.size() + 12 * kPoints);
  const std::filesystem::path kitti = dir / "kitti";
  std::filesystem::create_directories(kitti / "velodyne");
  testing::write_bytes(kitti / "calib.txt", "Tr: 1 0 0 0 0 1 0 0 0 0 1 0\n");
  testing::write_bytes(kitti / "poses.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n");
  testing::write_bytes(kitti / "velodyne" / "000000.bin", "");
  std::filesystem::resize_file(kitti / "velodyne" / "000000.bin", 16 * kPoints);
  for (const std::filesystem::path& input : {dir / "sparse.pcd", kitti}) {
    const CommandResult r = bgkmap("build -q " + input.string() + " -o " + (dir / "m.bgk").string() + " --max-memory 150M");
    expect_refusal(r, "(20000000 points) needs", input.string());
    EXPECT_NE(r.output.find("beyond --max-memory"), std::string::npos) << r.output;
  }
}

TEST(Reliability, MergeOfAMissingShardFolderNamesIt) {
  TempDir dir("reliability-merge");
  const CommandResult r = testing::run_command("cd " + dir.path().string() + " && " + BGKMAP_CLI + " merge missing -o m.bgk");
  expect_refusal(r, "missing: no such shard folder or manifest", "merge missing");  // named an empty folder ""
}

// Free points sampled every --free-resolution were allocated before any estimate (bgk grew to
// 2.6 GB, gpoctomap to 3.2 GB under --max-memory 1G).
TEST(Reliability, FreeSamplesAreEstimatedBeforeTheyAreSampled) {
  TempDir dir("reliability-samples");
  write_scan(dir / "s.pcd", {0.2f, 0.1f, 0.3f}, testing::random_scans(8, 1, 200, 1.5f)[0].points);
  for (const char* method : {"bgk", "gpoctomap", "bhm"}) {
    const std::string out = (dir / (std::string(method) == "bgk" ? "m.bgk" : "m.bt")).string();
    const CommandResult r = bgkmap("build -q " + (dir / "s.pcd").string() + " -o " + out + " --method " + method +
                                   " --free-resolution 1e-6 --max-memory 1G --backend cpu");
    expect_refusal(r, std::string(method) + "'s training points (scan 1", method);
    EXPECT_NE(r.output.find("a larger --free-resolution"), std::string::npos) << r.output;
  }
}

// A CARMEN log still being recorded: its SHA-256 no longer matched, so --resume added all its
// scans again (446 of 910 counted twice, rc 0). Now its held beginning is recognised by the hash
// of the bytes the map read, and a log that changed otherwise is refused.
TEST(Reliability, ResumeAddsOnlyTheNewScansOfALogThatGrew) {
  TempDir dir("reliability-grown");
  std::string log;
  for (int i = 0; i < 12; ++i) {
    const double x = 0.1 * i;
    log += "FLASER 5 1.0 1.2 1.5 1.1 0.9 " + std::to_string(x) + " 0.2 0.1 " + std::to_string(x) + " 0.2 0.1 " +
           std::to_string(10.0 + i) + " host " + std::to_string(10.0 + i) + "\n";
  }
  const size_t half = [&] {
    size_t at = 0;
    for (int line = 0; line < 7; ++line) at = log.find('\n', at) + 1;
    return at;
  }();
  const std::string flags = " -q --backend cpu --2d --max-range 3 ";
  testing::write_bytes(dir / "whole.log", log);
  ASSERT_EQ(bgkmap("build" + flags + (dir / "whole.log").string() + " -o " + (dir / "whole.bgk").string()).status, 0);
  testing::write_bytes(dir / "run.log", log.substr(0, half));
  ASSERT_EQ(bgkmap("build" + flags + (dir / "run.log").string() + " -o " + (dir / "part.bgk").string()).status, 0);
  testing::write_bytes(dir / "run.log", log);  // the recording went on
  const CommandResult resumed = bgkmap("build" + flags + (dir / "run.log").string() + " --resume " +
                                       (dir / "part.bgk").string() + " -o " + (dir / "resumed.bgk").string() +
                                       " --report " + (dir / "r.json").string());
  ASSERT_EQ(resumed.status, 0) << resumed.output;
  const std::string report = testing::read_bytes(dir / "r.json");
  EXPECT_NE(report.find("\"scans_already_held\": 7"), std::string::npos);
  EXPECT_NE(report.find("\"scans\": 5,"), std::string::npos);
  testing::expect_same_cells(read_native_map(dir / "whole.bgk"), read_native_map(dir / "resumed.bgk"));
  // Rewritten rather than grown: its 7 held scans can no longer be told apart.
  std::string changed = log;
  changed[changed.find("1.2")] = '2';
  testing::write_bytes(dir / "run.log", changed);
  expect_refusal(bgkmap("build" + flags + (dir / "run.log").string() + " --resume " + (dir / "part.bgk").string() +
                        " -o " + (dir / "x.bgk").string()),
                 "changed since the resumed map read 7 of its scans", "changed log");
}

// Usage errors were CLI11's two lines with its own exit codes (106, 114).
TEST(Reliability, UsageErrorsAreOneLineAndExitTwo) {
  for (const char* args : {"export m.bgk", "build s.pcd -o x.bgk --origin 0,0,1 --origin 1,1,1"}) {
    const CommandResult r = bgkmap(args);
    EXPECT_EQ(r.status, 2) << args << ": " << r.output;
    EXPECT_EQ(r.output.rfind("bgkmap: error: ", 0), 0u) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  }
  EXPECT_EQ(bgkmap("build --help").status, 0);
}

TEST(Reliability, RenderRefusesAHeightThatIsNotANumber) {
  TempDir dir("reliability-render");
  write_scan(dir / "s.pcd", {0.2f, 0.1f, 0.3f}, testing::random_scans(6, 1, 100, 1.5f)[0].points);
  ASSERT_EQ(bgkmap("build -q " + (dir / "s.pcd").string() + " -o " + (dir / "m.bgk").string() + " --backend cpu").status, 0);
  for (const char* z : {"nan", "inf"}) {  // nan rendered the default height, rc 0
    const CommandResult r = bgkmap("render " + (dir / "m.bgk").string() + " --z " + z + " -o " + (dir / "m.png").string());
    EXPECT_NE(r.status, 0) << z;
    EXPECT_NE(r.output.find("is not a finite height"), std::string::npos) << r.output;
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "m.png"));
}

// Config and scene files, and flags, are quoted in errors: a control byte among them (a newline, a
// terminal escape) was echoed as it was, so the "one line" broke or recoloured the terminal.
TEST(Reliability, ControlBytesOfFilesAndFlagsAreShownAsQuestionMarks) {
  TempDir dir("reliability-control");
  write_scan(dir / "s.pcd", {0.2f, 0.1f, 0.3f}, testing::random_scans(6, 1, 100, 1.5f)[0].points);
  testing::write_bytes(dir / "c.yaml", "resolution: 0.2\nbhm\x06spacing\x1b[31m: 0.25\n");
  testing::write_bytes(dir / "scene.yaml", "name: s\nseed\x1b]0;x\x07: 1\n");
  const std::string scan = (dir / "s.pcd").string(), out = " -o " + (dir / "m.bgk").string();
  const CommandResult config = bgkmap("build " + scan + " --config " + (dir / "c.yaml").string() + out);
  expect_refusal(config, "c.yaml: unknown parameter 'bhm?spacing?[31m'", "config key");
  const CommandResult scene = bgkmap("simulate " + (dir / "scene.yaml").string() + " -o " + (dir / "sim").string());
  expect_refusal(scene, "scene.yaml: ", "scene key");
  EXPECT_NE(scene.output.find("unknown key 'seed?]0;x?'"), std::string::npos) << scene.output;
  const CommandResult flag = bgkmap("build " + scan + out + " '--resolution\x1b[2J'");
  EXPECT_EQ(flag.status, 2) << flag.output;
  EXPECT_NE(flag.output.find("--resolution?[2J"), std::string::npos) << flag.output;
  for (const CommandResult* r : {&config, &scene, &flag})
    EXPECT_EQ(std::count_if(r->output.begin(), r->output.end(),
                            [](char c) { return (static_cast<unsigned char>(c) < 0x20 && c != '\n') || c == 0x7f; }),
              0) << r->output;
  EXPECT_FALSE(std::filesystem::exists(dir / "m.bgk"));
}

}  // namespace
}  // namespace bgkmap
