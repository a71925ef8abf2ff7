// CARMEN laser logs: the scans of small logs the tests write (plain and gzipped) against the
// documented geometry computed here in double; skipped messages counted; every malformed line,
// truncated or corrupted file an InputError naming the file (and the line); no-return readings
// never hits; and the shared Intel and FR-079 logs read whole.
#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/io/carmen_log.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

namespace fs = std::filesystem;
using testing::expect_input_error;
using testing::read_all_scans;
using testing::write_bytes;

constexpr double kPi = 3.14159265358979323846;

class TempDir : public testing::TempDir {
 public:
  TempDir() : testing::TempDir("carmen") {}
};

void write_gzip(const fs::path& file, const std::string& text) {
  gzFile gz = gzopen(file.c_str(), "wb");
  ASSERT_NE(gz, nullptr) << file;
  ASSERT_EQ(gzwrite(gz, text.data(), static_cast<unsigned>(text.size())), static_cast<int>(text.size()));
  ASSERT_EQ(gzclose(gz), Z_OK);
}

// A small log: two front scans, one rear scan and one ROBOTLASER1 among other messages.
const char* const kLog =
    "# message formats defined: PARAM SYNC ODOM FLASER RLASER\n"
    "PARAM robot_frontlaser_offset 0.0 nohost 0\n"
    "ODOM 0 0 0 0 0 0 0.000246 pippo 0.000246\n"
    "FLASER 4 1.0 2.5 81.83 0.5 1.5 -2.0 0.25 1.5 -2.0 0.25 10.5 pippo 10.5\n"
    "NEFF 15\r\n"
    "\n"
    "FLASER 3 3.0 0 nan 0.0 0.0 0.0 0.0 0.0 0.0 11.0 pippo\n"
    "RLASER 2 4.0 5.0 1 2 3.0 1 2 3.0 12.0 pippo 12.0\n"
    "ROBOTLASER1 0 -1.5 3.0 0.75 20.0 0.01 0 5 1 2 3 20.0 4 0 1.0 -1.0 0.5 1.0 -1.0 0.5 0 0 0 0 0 13.0 host 13.0\n"
    "FOO bar\n"
    "ODOM 1 1 1 0 0 0 14.0 pippo 14.0\n";

// Beam end in double: origin (x, y) plus r along angle a.
Vec3f end_point(double x, double y, double r, double a) {
  return {static_cast<float>(x + r * std::cos(a)), static_cast<float>(y + r * std::sin(a)), 0.0f};
}

void expect_point(const Vec3f& got, const Vec3f& want, const std::string& what) {
  EXPECT_NEAR(got.x, want.x, 1e-5) << what;
  EXPECT_NEAR(got.y, want.y, 1e-5) << what;
  EXPECT_EQ(got.z, 0.0f) << what;
}

void expect_log_scans(const std::vector<Scan>& scans) {
  ASSERT_EQ(scans.size(), 4u);
  // FLASER 4: beam i at theta - 90 deg + i * 45 deg.
  const Scan& a = scans[0];
  ASSERT_EQ(a.points.size(), 4u);
  EXPECT_FLOAT_EQ(a.pose.position.x, 1.5f);
  EXPECT_FLOAT_EQ(a.pose.position.y, -2.0f);
  EXPECT_EQ(a.pose.position.z, 0.0f);
  EXPECT_FLOAT_EQ(a.pose.qw, static_cast<float>(std::cos(0.125)));
  EXPECT_FLOAT_EQ(a.pose.qz, static_cast<float>(std::sin(0.125)));
  EXPECT_TRUE(a.points_in_world_frame);
  EXPECT_FLOAT_EQ(a.no_return_range_m, kCarmenNoReturnRangeM);
  const double r[] = {1.0, 2.5, 81.83, 0.5};
  for (int i = 0; i < 4; ++i)
    expect_point(a.points[i], end_point(1.5, -2.0, r[i], 0.25 - kPi / 2 + i * kPi / 4), "FLASER beam " + std::to_string(i));
  // Zero and NaN readings are no measurement: NaN points, dropped and counted by preprocessing.
  const Scan& b = scans[1];
  ASSERT_EQ(b.points.size(), 3u);
  expect_point(b.points[0], end_point(0, 0, 3.0, -kPi / 2), "second FLASER beam 0");
  EXPECT_TRUE(std::isnan(b.points[1].x));
  EXPECT_TRUE(std::isnan(b.points[2].x));
  // RLASER: the same convention with the pose of its line.
  const Scan& c = scans[2];
  ASSERT_EQ(c.points.size(), 2u);
  expect_point(c.points[0], end_point(1, 2, 4.0, 3.0 - kPi / 2), "RLASER beam 0");
  expect_point(c.points[1], end_point(1, 2, 5.0, 3.0), "RLASER beam 1");
  // ROBOTLASER1: explicit start angle and resolution; its own max range is the no-return range.
  const Scan& d = scans[3];
  ASSERT_EQ(d.points.size(), 5u);
  EXPECT_FLOAT_EQ(d.no_return_range_m, 20.0f);
  const double rr[] = {1, 2, 3, 20, 4};
  for (int i = 0; i < 5; ++i)
    expect_point(d.points[i], end_point(1.0, -1.0, rr[i], 0.5 - 1.5 + i * 0.75), "ROBOTLASER1 beam " + std::to_string(i));
}

TEST(CarmenLog, PlainAndGzippedLogsGiveTheDocumentedScans) {
  TempDir dir;
  write_bytes(dir / "small.log", kLog);
  write_gzip(dir / "small.clf.gz", kLog);
  for (const char* name : {"small.log", "small.clf.gz"}) {
    SCOPED_TRACE(name);
    ScanSource source({dir / name});
    std::vector<Scan> scans;
    Scan scan;
    while (source.next(scan)) scans.push_back(scan);
    expect_log_scans(scans);
    const std::map<std::string, uint64_t> skipped = {{"FOO", 1}, {"NEFF", 1}, {"ODOM", 2}, {"PARAM", 1}};
    EXPECT_EQ(source.skipped_messages(), skipped);
  }
  // A folder takes its logs (natural order) beside other scan files.
  EXPECT_EQ(read_all_scans({dir.path()}).size(), 8u);
}

TEST(CarmenLog, FileNamesAndTypes) {
  for (const char* name : {"a.log", "a.LOG", "a.clf", "a.gfs.log", "a.log.gz", "a.clf.gz", "a.gfs.log.GZ"})
    EXPECT_TRUE(is_carmen_log_name(name)) << name;
  for (const char* name : {"a.gz", "a.pcd.gz", "a.txt", "log", "a.log.bz2"}) EXPECT_FALSE(is_carmen_log_name(name)) << name;
  EXPECT_EQ(scan_file_type("x.gfs.log.gz"), ScanFileType::kCarmenLog);
}

// No-return readings through preprocessing, as every method takes them.
TEST(CarmenLog, NoReturnReadingsAreNeverHits) {
  TempDir dir;
  write_bytes(dir / "a.log", "FLASER 4 1.0 2.5 81.83 0.5 1.5 -2.0 0.25 1.5 -2.0 0.25 10.5 pippo 10.5\n");
  const Scan scan = read_all_scans({dir / "a.log"}).at(0);
  const Vec3f o = scan.pose.position;
  const auto range = [&](const Vec3f& p) { return std::hypot(double(p.x - o.x), double(p.y - o.y)); };
  for (double max_range : {0.0, 20.0, 100.0}) {
    SCOPED_TRACE("max range " + std::to_string(max_range));
    PreprocessParams params;
    params.max_range_m = max_range;
    ScanObservations obs;
    PreprocessCounts counts;
    preprocess_scan(scan, params, obs, counts);
    EXPECT_EQ(counts.no_returns, 1u);
    ASSERT_EQ(obs.hits.size(), 3u);
    for (const Vec3f& h : obs.hits) EXPECT_LT(range(h), 3.0);
    if (max_range == 0) {
      EXPECT_EQ(counts.no_returns_dropped, 1u);  // no max range: its free length is unknown
      EXPECT_EQ(obs.free_ends.size(), 3u);
      continue;
    }
    // A beam beyond the max range: free up to the max range along the no-return beam's direction.
    EXPECT_EQ(counts.no_returns_dropped, 0u);
    EXPECT_EQ(counts.beyond_max_range, 1u);
    ASSERT_EQ(obs.free_ends.size(), 4u);
    const Vec3f& f = obs.free_ends[2];
    EXPECT_NEAR(range(f), max_range, 1e-4);
    EXPECT_NEAR(std::atan2(f.y - o.y, f.x - o.x), 0.25 - kPi / 2 + 2 * kPi / 4, 1e-6);
    params.beyond_range = BeyondRange::kDrop;
    PreprocessCounts dropped;
    preprocess_scan(scan, params, obs, dropped);
    EXPECT_EQ(obs.free_ends.size(), 3u);
  }
}

TEST(CarmenLog, MalformedLinesNameFileAndLine) {
  TempDir dir;
  const fs::path file = dir / "bad.log";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"FLASER 5 1 2 3 4 0 0 0 0 0 0 1.0 host 1.0\n", "line 1: FLASER: 5 readings leave 'host' '1.0'"},
      {"FLASER 3 1 2 3 4 0 0 0 0 0 0 1.0 host 1.0\n", "line 1: FLASER: 3 readings give 13 or 14 fields, the line has 15"},
      {"FLASER 3 1 2 3 4 0 0 0 0 0 0 1.0 host\n", "line 1: FLASER: 3 readings leave '0' '1.0'"},
      {"FLASER 6 1 2 3 4 0 0 0 0 0 0 1.0 host 1.0\n", "line 1: FLASER: 6 readings give 16 or 17 fields"},
      {"FLASER 2 1 2 0 0 0 0 0 0 1.0\n", "line 1: FLASER: 2 readings give"},                 // cut short
      {"FLASER x 1 2\n", "line 1: FLASER: the reading count 'x'"},
      {"FLASER -1 1 2\n", "line 1: FLASER: the reading count '-1'"},
      {"FLASER 99999999999999999999 1\n", "line 1: FLASER: the reading count"},
      {"FLASER\n", "line 1: FLASER: the reading count (missing)"},
      {"ODOM 0\nFLASER 2 1 zz 0 0 0 0 0 0 1.0 host\n", "line 2: FLASER: reading 2 'zz' is not a number"},
      {"FLASER 2 1 2 0 nan 0 0 0 0 1.0 host\n", "line 1: FLASER: y is not finite"},
      {"RLASER 1 1 0 0 inf 0 0 0 1.0 host\n", "line 1: RLASER: theta is not finite"},
      {"ROBOTLASER1 0 -1.5 3 0.75 20 0.01 0 2 1 2 1 0.5 0 0 0 0 0 0 0 0 0 0 1.0 host 1.0\n",
       "line 1: ROBOTLASER1: 2 readings and 1 remissions leave 'host' '1.0'"},
      {"ROBOTLASER1 0 -1.5 3 0.75 20 0.01 0 2 1 2 9 0 0 0 0 0 0 0 0 0 0 0 1.0 host\n",
       "line 1: ROBOTLASER1: 2 readings and 9 remissions give 34 or 35 fields, the line has 25"},
      {"FLASER 1 1 0 0 0 0 0 0 1.0 host\n\x01\x02 junk\n", "line 2: binary data"},
  };
  for (const auto& [text, expected] : cases) {
    SCOPED_TRACE(text);
    write_bytes(file, text);
    expect_input_error(file, [&] { read_all_scans({file}); }, text);
    try {
      read_all_scans({file});
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
    }
  }
}

std::string gzip_bytes(const TempDir& dir, const std::string& text) {
  const fs::path tmp = dir / "tmp.gz";
  write_gzip(tmp, text);
  return testing::read_bytes(tmp);
}

// Every prefix of a gzipped log is a truncated gzip stream: an InputError, never fewer scans in silence.
TEST(CarmenLog, TruncatedGzipStreamsAreErrors) {
  TempDir dir;
  const std::string gz = gzip_bytes(dir, kLog);
  const fs::path file = dir / "cut.log.gz";
  for (size_t size = 1; size < gz.size(); ++size) {
    write_bytes(file, gz.substr(0, size));
    expect_input_error(file, [&] { read_all_scans({file}); }, "gzip cut at " + std::to_string(size));
  }
  write_bytes(file, gz);
  EXPECT_EQ(read_all_scans({file}).size(), 4u);
}

// A cut plain log (at every offset) and byte flips in plain and gzipped logs: a clean
// InputError or scans that the reader could parse, never a crash or another exception.
void expect_clean(const fs::path& file, const std::string& context, size_t max_scans) {
  try {
    EXPECT_LE(read_all_scans({file}).size(), max_scans) << context;
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), file) << context;
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << context;
  } catch (const std::exception& e) {
    ADD_FAILURE() << context << ": non-InputError " << e.what();
  }
}

TEST(CarmenLog, TruncationAndByteFlipsGiveCleanErrors) {
  TempDir dir;
  const std::string text = kLog;
  const fs::path plain = dir / "cut.log";
  for (size_t size = 0; size <= text.size(); ++size) {
    write_bytes(plain, text.substr(0, size));
    expect_clean(plain, "plain cut at " + std::to_string(size), 4);
  }
  const std::string gz = gzip_bytes(dir, kLog);
  const fs::path zipped = dir / "flip.log.gz";
  std::mt19937 rng(21);
  for (int trial = 0; trial < 400; ++trial) {
    const bool use_gz = trial % 2 == 0;
    std::string bytes = use_gz ? gz : text;
    const size_t at = rng() % bytes.size();
    bytes[at] = static_cast<char>(bytes[at] ^ (1 + rng() % 255));
    const fs::path& file = use_gz ? zipped : plain;
    write_bytes(file, bytes);
    // A flip can split a line in two (a flipped newline) or change a message type: at most one
    // more scan line than the log has.
    expect_clean(file, "flip at " + std::to_string(at) + (use_gz ? " (gz)" : ""), 5);
  }
}

// The shared logs: the scan and beam counts their README gives, and a beam checked against its line.
TEST(CarmenLog, SharedIntelAndFreiburgLogs) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  struct Expected {
    const char* file;
    size_t scans, beams, odom;
  };
  for (const Expected& e : {Expected{"carmen/intel-corrected.log.gz", 910, 180, 14541},
                            Expected{"carmen/freiburg-079-corrected.log.gz", 4791, 360, 9725}}) {
    SCOPED_TRACE(e.file);
    ScanSource source({datasets / e.file});
    Scan scan;
    size_t scans = 0, no_returns = 0;
    while (source.next(scan)) {
      ASSERT_EQ(scan.points.size(), e.beams) << "scan " << scans;
      for (const Vec3f& p : scan.points) {
        const double r = std::hypot(double(p.x - scan.pose.position.x), double(p.y - scan.pose.position.y));
        no_returns += r >= scan.no_return_range_m;
      }
      if (scans == 0 && e.beams == 180) {
        // The first Intel line: r_1 = 1.09 at x y theta = 0.600266 -0.0320327 -0.354665.
        expect_point(scan.points[0], end_point(0.600266, -0.0320327, 1.09, -0.354665 - kPi / 2), "Intel beam 0");
        expect_point(scan.points[179], end_point(0.600266, -0.0320327, 1.23, -0.354665 - kPi / 2 + 179 * kPi / 180),
                     "Intel beam 179");
      }
      ++scans;
    }
    EXPECT_EQ(scans, e.scans);
    EXPECT_EQ(source.skipped_messages().at("ODOM"), e.odom);
    EXPECT_EQ(source.skipped_messages().at("NEFF"), e.scans);
    // The readings of 81.83 (Intel: 4,172) and 81.91 (FR-079: 36,004) are the no returns.
    EXPECT_EQ(no_returns, e.beams == 180 ? 4172u : 36004u);
  }
}

}  // namespace
}  // namespace bgkmap
