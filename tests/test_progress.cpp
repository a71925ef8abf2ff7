// Progress that tells the truth: scans counted inside logs and sequences (known or estimated
// totals), the library's long phases reported through its callback, and the bar as the CLI draws
// it (-q, --progress, nothing on a pipe by default).
#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <regex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "bgkmap/io/pcd_io.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "core/progress_counter.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

namespace fs = std::filesystem;
using testing::CommandResult;

CommandResult run(const std::string& args) { return testing::run_command(std::string(BGKMAP_CLI) + " " + args); }

// A CARMEN log of `scans` FLASER lines of 180 beams in a 6 x 6 m room, an ODOM line after each.
std::string carmen_log(int scans) {
  std::string text = "# message formats defined: ODOM FLASER\nPARAM robot_length 0.5\n";
  char buf[64];
  for (int s = 0; s < scans; ++s) {
    const double x = 1.0 + 4.0 * s / scans, y = 3.0, theta = 0.01 * s;
    text += "FLASER 180";
    for (int i = 0; i < 180; ++i) {
      const double a = theta - M_PI / 2 + i * M_PI / 180;
      const double wall = std::min(std::abs((std::cos(a) > 0 ? 6.0 - x : x) / std::cos(a)),
                                   std::abs((std::sin(a) > 0 ? 6.0 - y : y) / (std::sin(a) + 1e-12)));
      std::snprintf(buf, sizeof buf, " %.3f", std::min(wall, 8.0));
      text += buf;
    }
    std::snprintf(buf, sizeof buf, " %.4f %.4f %.4f", x, y, theta);
    text += std::string(buf) + buf + " " + std::to_string(s) + ".5 host " + std::to_string(s) + ".5\n";
    text += "ODOM " + std::string(buf + 1) + " 0 0 0 " + std::to_string(s) + ".6 host " + std::to_string(s) + ".6\n";
  }
  return text;
}

void write_gzip(const fs::path& file, const std::string& text) {
  gzFile gz = gzopen(file.c_str(), "wb");
  ASSERT_NE(gz, nullptr);
  ASSERT_EQ(gzwrite(gz, text.data(), static_cast<unsigned>(text.size())), static_cast<int>(text.size()));
  gzclose(gz);
}

// The progress of a log is estimated from its bytes, near the truth after a tenth of it, and exact
// at its end.
void expect_log_progress(const fs::path& log, uint64_t scans, double tolerance) {
  ScanSource source({log});
  const ScanProgress before = source.progress();
  EXPECT_EQ(before.done, 0u);
  EXPECT_TRUE(before.estimated);
  Scan scan;
  for (uint64_t i = 1; i <= scans; ++i) {
    ASSERT_TRUE(source.next(scan)) << i;
    const ScanProgress p = source.progress();
    ASSERT_EQ(p.done, i);
    ASSERT_GE(p.total, p.done);
    ASSERT_TRUE(p.estimated) << i;
    if (i >= scans / 10) {
      EXPECT_NEAR(double(p.total), double(scans), tolerance * double(scans)) << log << " after " << i << " scans";
    }
  }
  EXPECT_FALSE(source.next(scan));
  const ScanProgress after = source.progress();
  EXPECT_EQ(after.done, scans);
  EXPECT_EQ(after.total, scans);
  EXPECT_FALSE(after.estimated);
}

TEST(ScanProgress, ALogsScansAreEstimatedFromItsBytesReadAndExactAtItsEnd) {
  const fs::path dir = testing::make_temp_dir("progress_log");
  const std::string text = carmen_log(400);
  testing::write_bytes(dir / "plain.log", text);
  write_gzip(dir / "packed.log.gz", text);
  expect_log_progress(dir / "plain.log", 400, 0.05);
  expect_log_progress(dir / "packed.log.gz", 400, 0.05);
  fs::remove_all(dir);
}

TEST(ScanProgress, ScanFilesAndKittiFoldersAreCountedBeforeAnyIsRead) {
  const fs::path dir = testing::make_temp_dir("progress_files");
  const auto scans = testing::random_scans(5, 3, 50, 2.0f);
  for (size_t i = 0; i < scans.size(); ++i) write_pcd(dir / ("s_" + std::to_string(i) + ".pcd"), scans[i]);
  const fs::path seq = dir / "seq";
  fs::create_directories(seq / "velodyne");
  testing::write_bytes(seq / "calib.txt", "Tr: 1 0 0 0 0 1 0 0 0 0 1 0\n");
  std::string poses;
  for (int s = 0; s < 4; ++s) {
    poses += "1 0 0 " + std::to_string(s) + " 0 1 0 0 0 0 1 0\n";
    const float point[4] = {1.0f, 2.0f, 0.5f, 0.0f};
    testing::write_bytes(seq / "velodyne" / ("00000" + std::to_string(s) + ".bin"),
                         std::string(reinterpret_cast<const char*>(point), sizeof point));
  }
  testing::write_bytes(seq / "poses.txt", poses);

  ScanSource source({dir, seq});  // the folder's 3 PCDs, then the sequence's 4 scans
  Scan scan;
  for (uint64_t done = 0;; ++done) {
    const ScanProgress p = source.progress();
    EXPECT_EQ(p.done, done);
    EXPECT_EQ(p.total, 7u);
    EXPECT_FALSE(p.estimated);
    if (!source.next(scan)) break;
  }
  EXPECT_EQ(source.progress().done, 7u);
  fs::remove_all(dir);
}

TEST(ScanProgress, AGraphsNodesAreCountedOnceItIsOpened) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  const fs::path graph = datasets / "octomap_samples/spherical_scan.graph";  // one node
  ScanSource source({graph, graph});
  ScanProgress p = source.progress();
  EXPECT_EQ(p.done, 0u);
  EXPECT_TRUE(p.estimated);  // not opened: guessed from the bytes
  Scan scan;
  ASSERT_TRUE(source.next(scan));
  p = source.progress();
  EXPECT_EQ(p.done, 1u);
  EXPECT_EQ(p.total, 2u);  // the first's node count, the second by the first's scans per byte
  EXPECT_TRUE(p.estimated);
  ASSERT_TRUE(source.next(scan));
  p = source.progress();
  EXPECT_EQ(p.done, 2u);
  EXPECT_EQ(p.total, 2u);
  EXPECT_FALSE(p.estimated);
  EXPECT_FALSE(source.next(scan));
}

TEST(ProgressCounter, ReportsFromOneThreadAtATimeInOrderAndEndsAtTheTotal) {
  constexpr uint64_t kTotal = 100000;
  std::vector<uint64_t> seen;
  std::atomic<int> inside{0};
  bool overlapped = false;
  const ProgressCallback callback = [&](const Progress& p) {
    if (inside.fetch_add(1) != 0) overlapped = true;
    EXPECT_EQ(p.phase, "work");
    EXPECT_EQ(p.unit, "items");
    EXPECT_EQ(p.total, kTotal);
    seen.push_back(p.done);
    inside.fetch_sub(1);
  };
  ProgressCounter counter(callback, "work", "items", kTotal);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&] {
      for (uint64_t i = 0; i < kTotal / 4; ++i) counter.add();
    });
  for (std::thread& t : threads) t.join();
  counter.finish();
  EXPECT_FALSE(overlapped);
  ASSERT_GE(seen.size(), 3u);
  EXPECT_EQ(seen.front(), 0u);
  EXPECT_EQ(seen.back(), kTotal);
  EXPECT_TRUE(std::is_sorted(seen.begin(), seen.end()));
  EXPECT_LE(seen.size(), 1002u);  // a report a thousandth at most, and the first and last
  ProgressCounter silent({}, "none", "items", 10);  // no callback: nothing to call
  silent.add(10);
  silent.finish();
}

// The bar's lines of `phase` in a command's output: done, total, whether the total was estimated,
// and whether the line gave a time left.
struct BarLine {
  uint64_t done, total;
  bool estimated, eta;
};
std::vector<BarLine> bar_lines(const std::string& output, const std::string& phase, const std::string& unit) {
  std::vector<BarLine> lines;
  const std::regex line("(^|\n)" + phase + " \\[[#.]{30}\\] ([0-9]+)/(~?)([0-9]+) " + unit +
                        " \\(([0-9]+)%\\) [0-9]+ s(, [0-9]+ s left)?(?=\n)");
  for (auto it = std::sregex_iterator(output.begin(), output.end(), line); it != std::sregex_iterator(); ++it)
    lines.push_back({std::stoull((*it)[2]), std::stoull((*it)[4]), (*it)[3].length() > 0, (*it)[6].length() > 0});
  return lines;
}

// A build's bar counts the scans inside its log: many distinct counts, totals near the log's (then
// its count exactly), a time left.
void expect_build_bar(const std::string& output, uint64_t scans) {
  const std::vector<BarLine> lines = bar_lines(output, "build", "scans");
  ASSERT_GE(lines.size(), 20u) << output.substr(0, 2000);
  std::set<uint64_t> counts;
  bool eta = false;
  for (const BarLine& l : lines) {
    counts.insert(l.done);
    eta |= l.eta;
    EXPECT_LE(l.done, l.total);
    if (l.done >= scans / 5) {
      EXPECT_NEAR(double(l.total), double(scans), 0.1 * double(scans)) << l.done;
    }
  }
  EXPECT_GE(counts.size(), 20u);
  EXPECT_TRUE(eta);
  EXPECT_EQ(lines.back().done, scans);
  EXPECT_EQ(lines.back().total, scans);
  EXPECT_FALSE(lines.back().estimated);
  EXPECT_TRUE(lines.front().estimated);
}

class ProgressCli : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = testing::make_temp_dir("progress_cli"); }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

TEST_F(ProgressCli, BuildOnALogShowsItsScansMovingIntoAPipeWithProgress) {
  write_gzip(dir_ / "room.log.gz", carmen_log(300));
  const std::string build = "build " + path("room.log.gz") + " -o " + path("m.bgk") + " --backend cpu --threads 1";
  CommandResult r = run(build + " --progress");
  ASSERT_EQ(r.status, 0) << r.output;
  expect_build_bar(r.output, 300);
  EXPECT_EQ(r.output.find('\r'), std::string::npos);  // a pipe gets whole lines, never redrawn ones

  r = run(build);  // not a terminal: no bar unless asked
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(r.output.find("build ["), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("bgkmap: 300 scans"), std::string::npos) << r.output;

  r = run(build + " -q --progress");  // quiet wins: nothing at all
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(r.output, "");

  std::string points;
  for (int i = 0; i < 2000; ++i) points += std::to_string(1 + i % 40 * 0.1) + " 3 0\n";
  testing::write_bytes(dir_ / "points.txt", points);
  const std::string query = "query " + path("m.bgk") + " --points " + path("points.txt");  // cells and bar both here
  r = run(query + " --progress");
  ASSERT_EQ(r.status, 0) << r.output;
  const std::vector<BarLine> lines = bar_lines(r.output, "query", "lines");
  ASSERT_GE(lines.size(), 50u) << r.output.substr(0, 2000);
  EXPECT_EQ(lines.back().done, 2000u);
  EXPECT_EQ(lines.back().total, 2000u);
  EXPECT_NEAR(double(lines[lines.size() / 2].total), 2000.0, 100.0);
  r = run(query);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(r.output.find("query ["), std::string::npos);
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 2000);  // the cells' lines alone
}

TEST_F(ProgressCli, TheFr079LogsBarCountsItsScans) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  const CommandResult r = run("build " + (datasets / "carmen/freiburg-079-corrected.log.gz").string() + " -o " +
                              path("fr079.bgk") + " --backend cpu --resolution 0.2 --progress");
  ASSERT_EQ(r.status, 0) << r.output;
  expect_build_bar(r.output, 4791);
}

TEST_F(ProgressCli, LongPhasesInsideTheMethodsAndEvalShowTheirOwnBars) {
  CommandResult r = run("simulate structured -q --sensor planar --scans 3 -o " + path("sim"));
  ASSERT_EQ(r.status, 0) << r.output;
  const std::string scans = path("sim/scans");

  r = run("build --method gpom " + scans + " -o " + path("g.ot") + " --threads 2 --progress");
  ASSERT_EQ(r.status, 0) << r.output;
  std::vector<BarLine> lines = bar_lines(r.output, "gpom prediction", "blocks");
  ASSERT_FALSE(lines.empty()) << r.output;
  EXPECT_GT(lines.back().total, 0u);
  EXPECT_EQ(lines.back().done, lines.back().total);
  EXPECT_EQ(bar_lines(r.output, "build", "scans").back().done, 3u);

  r = run("build --method bhm --bhm-gamma 0 --bhm-evidence-scans 2 " + scans + " -o " + path("b.ot") +
          " --ot-values mean --progress");
  ASSERT_EQ(r.status, 0) << r.output;
  lines = bar_lines(r.output, "bhm evidence search", "models");
  ASSERT_FALSE(lines.empty()) << r.output;
  EXPECT_GE(lines.back().total, 2u);  // the candidates and the chosen one
  EXPECT_EQ(lines.back().done, lines.back().total);

  r = run("eval " + path("b.ot") + " --truth " + path("sim/scene.yaml") + " --json " + path("e.json") + " --progress");
  ASSERT_EQ(r.status, 0) << r.output;
  lines = bar_lines(r.output, "score b\\.ot", "cells");
  ASSERT_FALSE(lines.empty()) << r.output;
  EXPECT_GT(lines.back().total, 1000u);
  EXPECT_EQ(lines.back().done, lines.back().total);
  EXPECT_NE(r.output.find("AUC"), std::string::npos);

  r = run("eval " + path("b.ot") + " --truth " + path("sim/scene.yaml") + " --json " + path("q.json") + " -q");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(r.output, "");
  EXPECT_TRUE(fs::exists(dir_ / "q.json"));
}

}  // namespace
}  // namespace bgkmap
