// Scan readers: PCD (through PCL) and OctoMap scan graphs (through liboctomap) give the points,
// origins and poses their files hold -- checked against the raw bytes, the header text and the
// libraries called directly -- and every truncated or corrupted file is an InputError naming it,
// never a crash or an allocation of what a corrupt count claims.
#include <gtest/gtest.h>
#include <octomap/ScanGraph.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>
#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <random>
#include <sstream>

#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/pcd_io.hpp"
#include "bgkmap/io/scan_graph_io.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

namespace fs = std::filesystem;


// Overwrites one byte in place (much faster than rewriting the file, for the flip sweeps).
void patch_byte(const fs::path& file, size_t at, char value) {
  std::fstream io(file, std::ios::binary | std::ios::in | std::ios::out);
  io.seekp(static_cast<std::streamoff>(at));
  io.put(value);
  ASSERT_TRUE(io.good()) << file;
}

using testing::expect_input_error;
using testing::read_all_scans;
using testing::write_bytes;

void expect_unreadable(const fs::path& file, const std::string& context) {
  expect_input_error(file, [&] { read_all_scans({file}); }, context);
}

// While alive, caps the address space a little above what the process uses now, so that a reader
// trusting an absurd count would fail with bad_alloc (a test failure) rather than quietly
// reserving gigabytes.
class AddressSpaceCap {
 public:
  AddressSpaceCap() {
    getrlimit(RLIMIT_AS, &saved_);
    std::ifstream status("/proc/self/status");
    std::string key;
    unsigned long long vm_kb = 0;
    while (status >> key) {
      if (key == "VmSize:") {
        status >> vm_kb;
        break;
      }
    }
    rlimit cap = saved_;
    cap.rlim_cur = static_cast<rlim_t>(vm_kb * 1024ull + (3ull << 30));
    if (saved_.rlim_max != RLIM_INFINITY && cap.rlim_cur > saved_.rlim_max) cap.rlim_cur = saved_.rlim_max;
    active_ = vm_kb > 0 && setrlimit(RLIMIT_AS, &cap) == 0;
  }
  ~AddressSpaceCap() {
    if (active_) setrlimit(RLIMIT_AS, &saved_);
  }

 private:
  rlimit saved_{};
  bool active_ = false;
};

// The PCD header read independently of the reader: keyword -> values, and where DATA ends.
struct PcdText {
  std::map<std::string, std::vector<std::string>> keys;
  size_t data_offset = 0;
};

PcdText parse_pcd_text(const std::string& bytes) {
  PcdText text;
  size_t pos = 0;
  while (pos < bytes.size()) {
    const size_t newline = bytes.find('\n', pos);
    std::istringstream line(bytes.substr(pos, newline - pos));
    pos = newline == std::string::npos ? bytes.size() : newline + 1;
    std::string key, value;
    line >> key;
    if (key.empty() || key[0] == '#') continue;
    while (line >> value) text.keys[key].push_back(value);
    if (key == "DATA") break;
  }
  text.data_offset = pos;
  return text;
}

Vec3f viewpoint_origin(const PcdText& text) {
  const auto& v = text.keys.at("VIEWPOINT");
  return {std::stof(v.at(0)), std::stof(v.at(1)), std::stof(v.at(2))};
}

bool same_float(float a, float b) { return (std::isnan(a) && std::isnan(b)) || a == b; }

void expect_same_points(const std::vector<Vec3f>& got, const std::vector<Vec3f>& want, const std::string& context) {
  ASSERT_EQ(got.size(), want.size()) << context;
  for (size_t i = 0; i < got.size(); ++i) {
    ASSERT_TRUE(same_float(got[i].x, want[i].x) && same_float(got[i].y, want[i].y) && same_float(got[i].z, want[i].z))
        << context << " point " << i << ": (" << got[i].x << ", " << got[i].y << ", " << got[i].z << ") vs ("
        << want[i].x << ", " << want[i].y << ", " << want[i].z << ")";
  }
}

std::vector<fs::path> shared_files(const fs::path& datasets, const std::string& extension) {
  std::vector<fs::path> files;
  for (const char* sub : {"sim_structured", "octomap_samples"}) {
    for (const auto& entry : fs::directory_iterator(datasets / sub))
      if (entry.path().extension() == extension) files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

// ---------------------------------------------------------------------------------------------
// natural_less and input expansion

TEST(NaturalLess, NumbersCompareByValue) {
  EXPECT_TRUE(natural_less("scan_2", "scan_10"));
  EXPECT_FALSE(natural_less("scan_10", "scan_2"));
  EXPECT_TRUE(natural_less("scan_9.pcd", "scan_10.pcd"));
  EXPECT_TRUE(natural_less("a2b3", "a2b12"));
  EXPECT_TRUE(natural_less("scan", "scan_1"));
  EXPECT_FALSE(natural_less("scan_1", "scan"));
  EXPECT_TRUE(natural_less("a", "b"));
  EXPECT_FALSE(natural_less("scan_3", "scan_3"));
  // Longer than any integer type: compared by digit count, then digits.
  EXPECT_TRUE(natural_less("s99999999999999999999999", "s100000000000000000000000"));
  // Equal values with different zero padding are still ordered, one way only.
  EXPECT_NE(natural_less("scan_01", "scan_1"), natural_less("scan_1", "scan_01"));
}

TEST(NaturalLess, SortsLikePeopleNumber) {
  std::vector<std::string> names = {"scan_10.pcd", "scan_1.pcd", "scan_2.pcd", "scan_100.pcd", "scan_02b.pcd",
                                    "scan_20.pcd", "scan_0.pcd", "other.pcd",  "scan_9.pcd"};
  std::mt19937 rng(7);
  for (int trial = 0; trial < 5; ++trial) {
    std::shuffle(names.begin(), names.end(), rng);
    std::sort(names.begin(), names.end(), natural_less);
    const std::vector<std::string> expected = {"other.pcd",  "scan_0.pcd",  "scan_1.pcd",  "scan_2.pcd",  "scan_02b.pcd",
                                               "scan_9.pcd", "scan_10.pcd", "scan_20.pcd", "scan_100.pcd"};
    EXPECT_EQ(names, expected);
  }
}

TEST(NaturalLess, IsAStrictOrder) {
  const std::vector<std::string> names = {"a", "a0", "a00", "a01", "a1", "a1b", "a10", "a2", "b", "_", "0", "00", ""};
  for (const auto& a : names) {
    EXPECT_FALSE(natural_less(a, a)) << a;
    for (const auto& b : names) {
      if (a != b) {
        EXPECT_NE(natural_less(a, b), natural_less(b, a)) << a << " / " << b;
      }
      for (const auto& c : names) {
        if (natural_less(a, b) && natural_less(b, c)) {
          EXPECT_TRUE(natural_less(a, c)) << a << " < " << b << " < " << c;
        }
      }
    }
  }
}

TEST(ScanSource, FolderExpandsToScanFilesInNaturalOrder) {
  const fs::path dir = testing::make_temp_dir("scan-source");
  for (const char* name : {"scan_10.pcd", "scan_2.pcd", "scan_1.graph", "SCAN_3.PCD", "notes.txt", "map.bt"})
    write_bytes(dir / name, "");
  fs::create_directories(dir / "nested.pcd");  // a folder, even with a scan extension, is not a scan
  write_bytes(dir / "nested.pcd" / "scan_0.pcd", "");
  const fs::path single = dir / "nested.pcd" / "scan_0.pcd";

  const ScanSource source({single, dir});
  const std::vector<fs::path> expected = {single, dir / "SCAN_3.PCD", dir / "scan_1.graph", dir / "scan_2.pcd",
                                          dir / "scan_10.pcd"};
  EXPECT_EQ(source.files(), expected);
  fs::remove_all(dir);
}

TEST(ScanSource, RejectsMissingUnsupportedAndEmptyInputs) {
  const fs::path dir = testing::make_temp_dir("scan-source-bad");
  const fs::path missing = dir / "does_not_exist.pcd";
  expect_input_error(missing, [&] { ScanSource source({missing}); }, "missing file");
  const fs::path missing_dir = dir / "no_such_folder";
  expect_input_error(missing_dir, [&] { ScanSource source({missing_dir}); }, "missing folder");

  for (const char* name : {"scan.txt", "scan.ply", "map.bt", "map.ot", "scan", "scan.pcd.bak"}) {
    write_bytes(dir / name, "x");
    expect_input_error(dir / name, [&] { ScanSource source({dir / name}); }, name);
  }
  const fs::path empty = dir / "empty";
  fs::create_directories(empty);
  expect_input_error(empty, [&] { ScanSource source({empty}); }, "empty folder");
  const fs::path no_scans = dir / "no_scans";
  fs::create_directories(no_scans);
  write_bytes(no_scans / "readme.md", "no scans here");
  write_bytes(no_scans / "map.bt", "");
  expect_input_error(no_scans, [&] { ScanSource source({no_scans}); }, "folder without scans");

  // A bad input anywhere in the list is found before any scan is read.
  write_bytes(dir / "ok.pcd", "");
  expect_input_error(dir / "map.bt", [&] { ScanSource source({dir / "ok.pcd", dir / "map.bt"}); }, "second input");
  EXPECT_THROW(ScanSource source(std::vector<fs::path>{}), InputError);
  fs::remove_all(dir);
}

TEST(ScanSource, ReadsOneFileAtATime) {
  // A corrupt file in the middle is only met when its turn comes: earlier scans are delivered.
  const fs::path dir = testing::make_temp_dir("scan-source-lazy");
  Scan scan;
  scan.points = {{1, 2, 3}};
  write_pcd(dir / "scan_1.pcd", scan);
  write_bytes(dir / "scan_2.pcd", "not a pcd file\n");
  write_pcd(dir / "scan_3.pcd", scan);
  ScanSource source({dir});
  ASSERT_EQ(source.files().size(), 3u);
  Scan got;
  ASSERT_TRUE(source.next(got));
  EXPECT_EQ(got.source, (dir / "scan_1.pcd").string());
  expect_input_error(dir / "scan_2.pcd", [&] { source.next(got); }, "corrupt second file");
  fs::remove_all(dir);
}

// A PCD without a pose of its own (PCL's default VIEWPOINT) is refused when met, naming the flags;
// --origin gives it one; beside a PCD with its own VIEWPOINT, or one whose header cannot be read
// to tell, --origin is refused before any scan is read.
TEST(ScanSource, PcdWithoutAViewpointTakesTheOriginOrIsRefused) {
  const fs::path dir = testing::make_temp_dir("scan-source-pose");
  Scan scan;
  scan.points = {{1, 2, 3}};
  scan.has_own_pose = false;  // written with PCL's default VIEWPOINT
  write_pcd(dir / "unposed.pcd", scan);
  EXPECT_NE(testing::read_bytes(dir / "unposed.pcd").find("\nVIEWPOINT 0 0 0 1 0 0 0\n"), std::string::npos);
  EXPECT_FALSE(read_pcd(dir / "unposed.pcd").has_own_pose);
  {
    ScanSource source({dir / "unposed.pcd"});
    Scan got;
    expect_input_error(dir / "unposed.pcd", [&] { source.next(got); }, "no pose");
    try {
      ScanSource again({dir / "unposed.pcd"});
      again.next(got);
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("give --origin X,Y,Z or --poses FILE"), std::string::npos) << e.what();
    }
  }
  ScanSourceOptions origin;
  origin.origin = Vec3f{1, 1, 0.1f};
  ScanSource source({dir / "unposed.pcd"}, origin);
  Scan got;
  ASSERT_TRUE(source.next(got));
  EXPECT_EQ(got.pose.position.x, 1.0f);
  EXPECT_EQ(got.pose.position.z, 0.1f);
  EXPECT_EQ(got.pose.qw, 1.0f);
  EXPECT_EQ(source.pose_sources().at("--origin"), 1u);
  scan.has_own_pose = true;
  scan.pose.position = {0, 0, 1};
  write_pcd(dir / "posed.pcd", scan);
  EXPECT_TRUE(read_pcd(dir / "posed.pcd").has_own_pose);
  // A scan given at the origin unturned is written so that it reads back as given.
  scan.pose.position = {0, 0, 0};
  write_pcd(dir / "at_origin.pcd", scan);
  EXPECT_NE(testing::read_bytes(dir / "at_origin.pcd").find("\nVIEWPOINT 0 0 0 -1 0 0 0\n"), std::string::npos);
  EXPECT_TRUE(read_pcd(dir / "at_origin.pcd").has_own_pose);
  expect_input_error(dir / "posed.pcd", [&] { ScanSource s({dir / "unposed.pcd", dir / "posed.pcd"}, origin); },
                     "own VIEWPOINT beside --origin");
  // The same identity at the origin written with qw = -1 is not PCL's default: a pose given.
  write_bytes(dir / "negated.pcd", "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\n"
                                   "VIEWPOINT 0 0 0 -1 0 0 0\nPOINTS 1\nDATA ascii\n1 2 3\n");
  ASSERT_TRUE(ScanSource({dir / "negated.pcd"}).next(got));
  EXPECT_EQ(got.pose.position.x, 0.0f);
  write_bytes(dir / "broken.pcd", "VERSION 0.7\nFIELDS x y\n");
  expect_input_error(dir / "broken.pcd", [&] { ScanSource s({dir / "broken.pcd"}, origin); }, "header unreadable");
  fs::remove_all(dir);
}

TEST(ScanSource, SharedBtMapsAreNotScans) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  for (const fs::path& bt : shared_files(datasets, ".bt")) {
    expect_input_error(bt, [&] { ScanSource source({bt}); }, "a .bt map passed as a scan");
  }
}

// ---------------------------------------------------------------------------------------------
// PCD

TEST(ReadPcd, SimStructuredScansMatchTheirBytes) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  const fs::path folder = datasets / "sim_structured";
  const std::vector<fs::path> files = shared_files(datasets, ".pcd");
  ASSERT_EQ(files.size(), 12u);
  for (const fs::path& file : files) {
    const std::string bytes = testing::read_bytes(file);
    const PcdText text = parse_pcd_text(bytes);
    ASSERT_EQ(text.keys.at("FIELDS"), (std::vector<std::string>{"x", "y", "z", "intensity"})) << file;
    ASSERT_EQ(text.keys.at("DATA"), std::vector<std::string>{"binary"}) << file;
    const size_t points = std::stoul(text.keys.at("POINTS").at(0));
    ASSERT_GE(bytes.size(), text.data_offset + points * 16) << file;  // zero padding follows

    const Scan scan = read_pcd(file);
    ASSERT_EQ(scan.points.size(), 3500u) << file;
    const Vec3f origin = viewpoint_origin(text);
    EXPECT_EQ(scan.pose.position.x, origin.x) << file;
    EXPECT_EQ(scan.pose.position.y, origin.y) << file;
    EXPECT_EQ(scan.pose.position.z, origin.z) << file;
    EXPECT_EQ(scan.pose.qw, 1.0f);
    EXPECT_EQ(scan.pose.qx, 0.0f);
    EXPECT_EQ(scan.pose.qy, 0.0f);
    EXPECT_EQ(scan.pose.qz, 0.0f);
    std::vector<Vec3f> raw(points);
    for (size_t i = 0; i < points; ++i) std::memcpy(&raw[i], bytes.data() + text.data_offset + 16 * i, 12);
    expect_same_points(scan.points, raw, file.string());
  }

  // The folder gives the same scans in file order; the .bt beside them is skipped.
  const std::vector<Scan> scans = read_all_scans({folder});
  ASSERT_EQ(scans.size(), 12u);
  for (size_t i = 0; i < scans.size(); ++i) {
    EXPECT_EQ(fs::path(scans[i].source).filename(), files[i].filename());
    EXPECT_EQ(scans[i].points.size(), 3500u);
  }
}

Scan random_scan(uint32_t seed, int points) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-20.f, 20.f);
  Scan scan;
  for (int i = 0; i < points; ++i) scan.points.push_back({u(rng), u(rng), u(rng)});
  scan.pose.position = {u(rng), u(rng), u(rng)};
  const float qw = u(rng), qx = u(rng), qy = u(rng), qz = u(rng);
  const float n = std::sqrt(qw * qw + qx * qx + qy * qy + qz * qz);
  scan.pose.qw = qw / n;
  scan.pose.qx = qx / n;
  scan.pose.qy = qy / n;
  scan.pose.qz = qz / n;
  return scan;
}

TEST(ReadPcd, WritePcdRoundTripIsExact) {
  const fs::path dir = testing::make_temp_dir("pcd-roundtrip");
  Scan scan = random_scan(11, 1000);
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  scan.points[3] = {nan, nan, nan};
  scan.points[4] = {1, nan, 2};
  scan.points[5] = {inf, -inf, 0};
  scan.points[6] = {-0.0f, 1e-38f, 3.4e38f};
  write_pcd(dir / "scan.pcd", scan);
  const Scan back = read_pcd(dir / "scan.pcd");
  expect_same_points(back.points, scan.points, "round trip");  // NaN/Inf kept for preprocessing
  EXPECT_EQ(back.pose.position.x, scan.pose.position.x);
  EXPECT_EQ(back.pose.position.y, scan.pose.position.y);
  EXPECT_EQ(back.pose.position.z, scan.pose.position.z);
  // A unit quaternion normalised again may move by an ulp.
  EXPECT_NEAR(back.pose.qw, scan.pose.qw, 2e-7);
  EXPECT_NEAR(back.pose.qx, scan.pose.qx, 2e-7);
  EXPECT_NEAR(back.pose.qy, scan.pose.qy, 2e-7);
  EXPECT_NEAR(back.pose.qz, scan.pose.qz, 2e-7);
  EXPECT_EQ(back.source, (dir / "scan.pcd").string());

  // PCL reads our files too, with the same points.
  pcl::PointCloud<pcl::PointXYZ> cloud;
  ASSERT_EQ(pcl::io::loadPCDFile((dir / "scan.pcd").string(), cloud), 0);
  ASSERT_EQ(cloud.size(), scan.points.size());
  EXPECT_EQ(cloud[10].x, scan.points[10].x);
  EXPECT_EQ(cloud.sensor_origin_.x(), scan.pose.position.x);

  Scan empty;
  empty.pose.position = {1.5f, -2.f, 0.25f};
  write_pcd(dir / "empty.pcd", empty);
  const Scan empty_back = read_pcd(dir / "empty.pcd");
  EXPECT_TRUE(empty_back.points.empty());
  EXPECT_EQ(empty_back.pose.position.x, 1.5f);
  EXPECT_EQ(empty_back.pose.position.z, 0.25f);
  fs::remove_all(dir);
}

TEST(ReadPcd, PclWrittenAsciiAndCompressedFilesReadExactly) {
  const fs::path dir = testing::make_temp_dir("pcd-pcl");
  const Scan reference = random_scan(5, 777);
  pcl::PointCloud<pcl::PointXYZI> cloud;
  for (size_t i = 0; i < reference.points.size(); ++i) {
    pcl::PointXYZI p;
    p.x = reference.points[i].x;
    p.y = reference.points[i].y;
    p.z = reference.points[i].z;
    p.intensity = static_cast<float>(i);
    cloud.push_back(p);
  }
  const float nan = std::numeric_limits<float>::quiet_NaN();
  cloud[0].x = cloud[0].y = cloud[0].z = nan;
  cloud[1].y = nan;
  cloud.is_dense = false;
  cloud.sensor_origin_ = Eigen::Vector4f(reference.pose.position.x, reference.pose.position.y,
                                         reference.pose.position.z, 0);
  cloud.sensor_orientation_ =
      Eigen::Quaternionf(reference.pose.qw, reference.pose.qx, reference.pose.qy, reference.pose.qz);
  std::vector<Vec3f> expected;
  for (const auto& p : cloud) expected.push_back({p.x, p.y, p.z});

  ASSERT_EQ(pcl::PCDWriter().writeASCII((dir / "ascii.pcd").string(), cloud, 9), 0);  // 9 digits: exact floats
  ASSERT_EQ(pcl::io::savePCDFileBinaryCompressed((dir / "compressed.pcd").string(), cloud), 0);
  ASSERT_EQ(pcl::io::savePCDFileBinary((dir / "binary.pcd").string(), cloud), 0);
  pcl::PointCloud<pcl::PointXYZI> organized = cloud;
  organized.resize(777);
  organized.width = 37;
  organized.height = 21;
  ASSERT_EQ(pcl::io::savePCDFileBinaryCompressed((dir / "organized.pcd").string(), organized), 0);

  for (const char* name : {"ascii.pcd", "compressed.pcd", "binary.pcd", "organized.pcd"}) {
    const fs::path file = dir / name;
    const PcdText text = parse_pcd_text(testing::read_bytes(file));
    const Scan scan = read_pcd(file);
    expect_same_points(scan.points, expected, name);
    // PCL prints VIEWPOINT with 6 digits: compare with what the file says.
    const Vec3f origin = viewpoint_origin(text);
    EXPECT_EQ(scan.pose.position.x, origin.x) << name;
    EXPECT_EQ(scan.pose.position.y, origin.y) << name;
    EXPECT_EQ(scan.pose.position.z, origin.z) << name;
    const auto& v = text.keys.at("VIEWPOINT");
    Eigen::Quaternionf q(std::stof(v[3]), std::stof(v[4]), std::stof(v[5]), std::stof(v[6]));
    q.normalize();
    EXPECT_NEAR(scan.pose.qw, q.w(), 1e-6) << name;
    EXPECT_NEAR(scan.pose.qx, q.x(), 1e-6) << name;
    EXPECT_NEAR(scan.pose.qy, q.y(), 1e-6) << name;
    EXPECT_NEAR(scan.pose.qz, q.z(), 1e-6) << name;
    EXPECT_NEAR(scan.pose.position.x, reference.pose.position.x, 1e-4 * std::abs(reference.pose.position.x)) << name;
  }
  fs::remove_all(dir);
}

TEST(ReadPcd, HandWrittenVariants) {
  const fs::path dir = testing::make_temp_dir("pcd-variants");
  const std::string head = "FIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\n";
  // Doubles, CRLF line ends, no VIEWPOINT (origin 0, identity), comments and empty lines.
  write_bytes(dir / "doubles.pcd", "# comment\r\nVERSION .7\r\n" +
                                       std::string("FIELDS x y z\r\nSIZE 8 8 8\r\nTYPE F F F\r\nCOUNT 1 1 1\r\n") +
                                       "WIDTH 2\r\nHEIGHT 1\r\nPOINTS 2\r\nDATA ascii\r\n0.5 -1.25 3e2\r\nnan +7 -0\r\n");
  const Scan scan = read_pcd(dir / "doubles.pcd");
  ASSERT_EQ(scan.points.size(), 2u);
  EXPECT_EQ(scan.points[0].x, 0.5f);
  EXPECT_EQ(scan.points[0].y, -1.25f);
  EXPECT_EQ(scan.points[0].z, 300.f);
  EXPECT_TRUE(std::isnan(scan.points[1].x));
  EXPECT_EQ(scan.points[1].y, 7.f);
  EXPECT_EQ(scan.pose.position.x, 0.f);
  EXPECT_EQ(scan.pose.qw, 1.f);

  // Binary doubles with x y z not first, among other fields.
  std::string binary = "VERSION 0.7\nFIELDS rgb z x y\nSIZE 4 8 8 8\nTYPE U F F F\nCOUNT 1 1 1 1\nWIDTH 1\n"
                       "HEIGHT 1\nVIEWPOINT 1 2 3 0 0 0 2\nPOINTS 1\nDATA binary\n";
  const uint32_t rgb = 0xffffffff;
  const double z = 6, x = 4, y = 5;
  binary.append(reinterpret_cast<const char*>(&rgb), 4).append(reinterpret_cast<const char*>(&z), 8);
  binary.append(reinterpret_cast<const char*>(&x), 8).append(reinterpret_cast<const char*>(&y), 8);
  write_bytes(dir / "mixed.pcd", binary);
  const Scan mixed = read_pcd(dir / "mixed.pcd");
  ASSERT_EQ(mixed.points.size(), 1u);
  EXPECT_EQ(mixed.points[0].x, 4.f);
  EXPECT_EQ(mixed.points[0].y, 5.f);
  EXPECT_EQ(mixed.points[0].z, 6.f);
  EXPECT_EQ(mixed.pose.position.z, 3.f);
  EXPECT_EQ(mixed.pose.qz, 1.f);  // (0 0 0 2) normalised
  EXPECT_EQ(mixed.pose.qw, 0.f);

  // What PCL itself would read as zeros or silently re-interpret must be refused.
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"short_line", head + "POINTS 2\nDATA ascii\n1 2 3\n4 5\n"},
      {"long_line", head + "POINTS 2\nDATA ascii\n1 2 3\n4 5 6 7\n"},
      {"word", head + "POINTS 2\nDATA ascii\n1 2 3\n4 five 6\n"},
      {"comment_in_data", head + "POINTS 2\nDATA ascii\n1 2 3\n# 4 5 6\n"},
      {"extra_point", head + "POINTS 2\nDATA ascii\n1 2 3\n4 5 6\n7 8 9\n"},
      {"missing_point", head + "POINTS 2\nDATA ascii\n1 2 3\n"},
      {"keyword_after_data", head + "POINTS 2\nDATA ascii\nVIEWPOINT 5 5 5 1 0 0 0\n1 2 3\n4 5 6\n"},
      {"blank_header_line", "FIELDS x y z\n \nSIZE 8 8 8\nTYPE F F F\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2 3\n"},
      {"out_of_order", "FIELDS x y z\nTYPE F F F\nSIZE 8 8 8\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2 3\n"},
      {"twice", head + "POINTS 2\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n"},
      {"no_z", "FIELDS x y\nSIZE 4 4\nTYPE F F\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2\n"},
      {"integer_x", "FIELDS x y z\nSIZE 4 4 4\nTYPE I F F\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2 3\n"},
      {"x_twice", "FIELDS x y z x\nSIZE 4 4 4 4\nTYPE F F F F\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2 3 4\n"},
      {"nan_viewpoint", head + "VIEWPOINT nan 0 0 1 0 0 0\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n"},
      {"zero_quaternion", head + "VIEWPOINT 0 0 0 0 0 0 0\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n"},
      {"short_viewpoint", head + "VIEWPOINT 0 0 0 1 0 0\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n"},
      {"no_data_line", head + "POINTS 2\n"},
      {"compressed_sizes_missing", head + "POINTS 2\nDATA binary_compressed\n"},
      {"huge_width", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 99999999999\nPOINTS 1\nDATA binary\n"},
      {"negative_width", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH -1\nPOINTS 1\nDATA binary\n"},
  };
  for (const auto& [name, content] : bad) {
    const fs::path file = dir / (name + ".pcd");
    write_bytes(file, content);
    expect_unreadable(file, name);
  }
  fs::remove_all(dir);
}

// ---------------------------------------------------------------------------------------------
// OctoMap scan graphs

TEST(ReadScanGraph, SphericalScanMatchesLiboctomap) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  const fs::path file = datasets / "octomap_samples" / "spherical_scan.graph";
  const std::vector<Scan> scans = read_all_scans({file});
  ASSERT_EQ(scans.size(), 1u);
  const Scan& scan = scans[0];
  ASSERT_EQ(scan.points.size(), 10201u);

  octomap::ScanGraph graph;
  ASSERT_TRUE(graph.readBinary(file.string()));
  graph.transformScans();
  ASSERT_EQ(graph.size(), 1u);
  const octomap::ScanNode& node = **graph.begin();
  ASSERT_EQ(node.scan->size(), 10201u);
  std::vector<Vec3f> expected;
  for (const auto& p : *node.scan) expected.push_back({p.x(), p.y(), p.z()});
  expect_same_points(scan.points, expected, "liboctomap");
  EXPECT_EQ(scan.pose.position.x, node.pose.trans().x());
  EXPECT_EQ(scan.pose.position.y, node.pose.trans().y());
  EXPECT_EQ(scan.pose.position.z, node.pose.trans().z());
  EXPECT_EQ(scan.pose.qw, node.pose.rot().u());
  EXPECT_EQ(scan.pose.qx, node.pose.rot().x());

  // Independently of liboctomap: this node's pose is a pure translation, so world points are
  // the stored sensor-frame doubles plus the origin.
  EXPECT_EQ(scan.pose.qw, 1.f);
  EXPECT_EQ(scan.pose.qx, 0.f);
  EXPECT_EQ(scan.pose.qy, 0.f);
  EXPECT_EQ(scan.pose.qz, 0.f);
  const std::string bytes = testing::read_bytes(file);
  for (size_t i : {size_t(0), size_t(1), size_t(5000), size_t(10200)}) {
    double raw[3];
    std::memcpy(raw, bytes.data() + 8 + 28 * i + 4, sizeof raw);
    EXPECT_EQ(scan.points[i].x, static_cast<float>(raw[0]) + scan.pose.position.x) << i;
    EXPECT_EQ(scan.points[i].y, static_cast<float>(raw[1]) + scan.pose.position.y) << i;
    EXPECT_EQ(scan.points[i].z, static_cast<float>(raw[2]) + scan.pose.position.z) << i;
  }
  double raw_origin[3];
  std::memcpy(raw_origin, bytes.data() + 8 + 28 * 10201 + 4, sizeof raw_origin);
  EXPECT_EQ(scan.pose.position.x, static_cast<float>(raw_origin[0]));
  EXPECT_EQ(scan.pose.position.y, static_cast<float>(raw_origin[1]));
  EXPECT_EQ(scan.pose.position.z, static_cast<float>(raw_origin[2]));
}

TEST(ReadScanGraph, MultiNodeGraphWithRotationsIsWorldFrame) {
  const fs::path dir = testing::make_temp_dir("graph");
  std::vector<std::vector<Vec3f>> sensor_points;
  {
    octomap::ScanGraph graph;
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(-5.f, 5.f);
    for (int k = 0; k < 4; ++k) {
      auto* cloud = new octomap::Pointcloud();  // the graph owns it
      std::vector<Vec3f> pts;
      const int n = k == 2 ? 0 : 100 + 37 * k;  // node 2 is an empty scan
      for (int i = 0; i < n; ++i) {
        pts.push_back({u(rng), u(rng), u(rng)});
        cloud->push_back(pts.back().x, pts.back().y, pts.back().z);
      }
      sensor_points.push_back(pts);
      graph.addNode(cloud, octomap::pose6d(u(rng), u(rng), u(rng), 0.3 * k, -0.2 * k, 1.1 * k));
      graph.connectPrevious();
    }
    ASSERT_TRUE(graph.writeBinary((dir / "walk.graph").string()));
  }
  const std::vector<Scan> scans = read_all_scans({dir / "walk.graph"});
  ASSERT_EQ(scans.size(), 4u);

  octomap::ScanGraph graph;
  ASSERT_TRUE(graph.readBinary((dir / "walk.graph").string()));
  graph.transformScans();
  size_t k = 0;
  for (auto it = graph.begin(); it != graph.end(); ++it, ++k) {
    const Scan& scan = scans[k];
    std::vector<Vec3f> expected;
    for (const auto& p : *(*it)->scan) expected.push_back({p.x(), p.y(), p.z()});
    expect_same_points(scan.points, expected, "node " + std::to_string(k));
    EXPECT_EQ(scan.pose.position.x, (*it)->pose.trans().x());
    EXPECT_EQ(scan.pose.qz, (*it)->pose.rot().z());
    // Our own pose math agrees: the points are the sensor-frame points moved by the pose.
    for (size_t i = 0; i < sensor_points[k].size(); ++i) {
      const Vec3f w = scan.pose.transform(sensor_points[k][i]);
      EXPECT_NEAR(scan.points[i].x, w.x, 1e-4);
      EXPECT_NEAR(scan.points[i].y, w.y, 1e-4);
      EXPECT_NEAR(scan.points[i].z, w.z, 1e-4);
    }
  }
  EXPECT_TRUE(scans[2].points.empty());

  // An empty graph is no scans, not an error; the reader is lazy, one node per call.
  { octomap::ScanGraph empty; ASSERT_TRUE(empty.writeBinary((dir / "empty.graph").string())); }
  EXPECT_TRUE(read_all_scans({dir / "empty.graph"}).empty());
  ScanGraphReader reader(dir / "walk.graph");
  EXPECT_EQ(reader.node_count(), 4u);
  Scan first;
  ASSERT_TRUE(reader.next(first));
  EXPECT_EQ(first.points.size(), 100u);
  fs::remove_all(dir);
}

// ---------------------------------------------------------------------------------------------
// Truncated and corrupted copies of every shared file

// Where a file's header ends (after the DATA line for PCD, after the node count for a graph)
// and its data: the shared PCD files carry zero padding after their points, which may go.
std::pair<size_t, size_t> header_and_data_end(const fs::path& file, const std::string& bytes) {
  if (file.extension() != ".pcd") return {4, bytes.size()};
  const PcdText text = parse_pcd_text(bytes);
  return {text.data_offset, text.data_offset + 16 * std::stoul(text.keys.at("POINTS").at(0))};
}

TEST(CorruptScans, TruncatedCopiesOfSharedFiles) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  const AddressSpaceCap cap;
  const fs::path dir = testing::make_temp_dir("truncated");
  std::vector<fs::path> files = shared_files(datasets, ".pcd");
  const std::vector<fs::path> graphs = shared_files(datasets, ".graph");
  files.insert(files.end(), graphs.begin(), graphs.end());
  ASSERT_EQ(files.size(), 13u);
  for (const fs::path& original : files) {
    const std::string bytes = testing::read_bytes(original);
    const auto [head, end] = header_and_data_end(original, bytes);
    const std::vector<size_t> cuts = {0,        1,        3,           10,       head / 2, head - 1,
                                      head,     head + 1, head + 7,    head + 9, (head + end) / 2,
                                      end - 29, end - 9,  end - 4,     end - 1};
    for (size_t cut : cuts) {
      const fs::path copy = dir / ("cut_" + std::to_string(cut) + "_" + original.filename().string());
      write_bytes(copy, bytes.substr(0, cut));
      expect_unreadable(copy, original.filename().string() + " cut at " + std::to_string(cut));
    }
  }
  fs::remove_all(dir);
}

// Replaces the first `from` with `to`; the test fails if `from` is absent.
std::string replaced(std::string bytes, const std::string& from, const std::string& to) {
  const size_t at = bytes.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) bytes.replace(at, from.size(), to);
  return bytes;
}

TEST(CorruptScans, CorruptedPcdHeadersAndData) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  const AddressSpaceCap cap;
  const fs::path dir = testing::make_temp_dir("corrupt-pcd");
  for (const fs::path& original : shared_files(datasets, ".pcd")) {
    const std::string bytes = testing::read_bytes(original);
    const PcdText text = parse_pcd_text(bytes);
    const std::string tag = original.stem().string();
    const std::map<std::string, std::string> variants = {
        {"absurd_points", replaced(replaced(bytes, "WIDTH 3500", "WIDTH 4294967295"), "POINTS 3500", "POINTS 4294967295")},
        {"absurd_points_only", replaced(bytes, "POINTS 3500", "POINTS 4000000000")},
        {"more_points", replaced(replaced(bytes, "WIDTH 3500", "WIDTH 350000"), "POINTS 3500", "POINTS 350000")},
        {"organized_lie", replaced(bytes, "HEIGHT 1", "HEIGHT 9")},
        {"huge_count", replaced(bytes, "COUNT 1 1 1 1", "COUNT 1 1 1 1000000")},
        {"bad_size", replaced(bytes, "SIZE 4 4 4 4", "SIZE 4 4 4 9")},
        {"bad_type", replaced(bytes, "TYPE F F F F", "TYPE F F F Q")},
        {"bad_encoding", replaced(bytes, "DATA binary", "DATA binarx")},
        {"as_compressed", replaced(bytes, "DATA binary", "DATA binary_compressed")},
        {"as_ascii", replaced(bytes, "DATA binary", "DATA ascii")},
        {"no_x", replaced(bytes, "FIELDS x y z", "FIELDS a y z")},
        {"keyword_after_data", replaced(bytes, "DATA binary\n", "DATA binary\nPOINTS 999999999\n")},
        {"garbage_header", std::string(text.data_offset, '\x9c') + bytes.substr(text.data_offset)},
        {"header_only", bytes.substr(0, text.data_offset)},
        {"empty", ""},
    };
    for (const auto& [name, content] : variants) {
      const fs::path copy = dir / (tag + "_" + name + ".pcd");
      write_bytes(copy, content);
      expect_unreadable(copy, tag + " " + name);
    }

    // Flipping a bit anywhere in the header gives either a well-formed scan or an InputError;
    // in a keyword it must be the error.
    std::vector<bool> keyword(text.data_offset, false);  // first word of each non-comment line
    for (size_t line = 0; line < text.data_offset; line = bytes.find('\n', line) + 1) {
      if (bytes[line] == '#') continue;
      for (size_t at = line; at < text.data_offset && bytes[at] != ' ' && bytes[at] != '\n'; ++at) keyword[at] = true;
    }
    size_t rejected = 0, keyword_bytes = 0;
    const fs::path copy = dir / (tag + "_flipped.pcd");
    write_bytes(copy, bytes);
    for (size_t at = 0; at < text.data_offset; ++at) {
      const bool in_keyword = keyword[at];
      for (char mask : {'\x01', '\x80'}) {
        patch_byte(copy, at, static_cast<char>(bytes[at] ^ mask));
        try {
          const Scan scan = read_pcd(copy);
          EXPECT_FALSE(in_keyword) << tag << " byte " << at << " read fine after a keyword flip";
          EXPECT_EQ(scan.points.size(), 3500u) << tag << " byte " << at;
          for (float v : {scan.pose.position.x, scan.pose.position.y, scan.pose.position.z, scan.pose.qw})
            EXPECT_TRUE(std::isfinite(v)) << tag << " byte " << at;
        } catch (const InputError& e) {
          EXPECT_EQ(e.file(), copy);
          ++rejected;
        }
      }
      patch_byte(copy, at, bytes[at]);
      keyword_bytes += in_keyword;
    }
    EXPECT_GT(keyword_bytes, 40u) << tag;
    EXPECT_GE(rejected, 2 * keyword_bytes) << tag;
  }
  fs::remove_all(dir);
}

TEST(CorruptScans, CorruptedCompressedPcd) {
  const AddressSpaceCap cap;
  const fs::path dir = testing::make_temp_dir("corrupt-lzf");
  const Scan reference = random_scan(9, 2000);
  pcl::PointCloud<pcl::PointXYZ> cloud;
  for (const Vec3f& p : reference.points) cloud.push_back(pcl::PointXYZ(p.x, p.y, p.z));
  ASSERT_EQ(pcl::io::savePCDFileBinaryCompressed((dir / "good.pcd").string(), cloud), 0);
  const std::string bytes = testing::read_bytes(dir / "good.pcd");
  const size_t data = parse_pcd_text(bytes).data_offset;
  ASSERT_EQ(read_pcd(dir / "good.pcd").points.size(), 2000u);

  auto with_u32 = [&](size_t at, uint32_t v) {
    std::string b = bytes;
    std::memcpy(&b[at], &v, 4);
    return b;
  };
  const std::map<std::string, std::string> variants = {
      {"huge_compressed_size", with_u32(data, 0xffffffffu)},
      {"huge_uncompressed_size", with_u32(data + 4, 0xffffffffu)},
      {"small_uncompressed_size", with_u32(data + 4, 12)},
      {"zero_compressed_size", with_u32(data, 0)},
      {"truncated_block", bytes.substr(0, bytes.size() - 100)},
      {"garbage_block", bytes.substr(0, data + 8) + std::string(bytes.size() - data - 8, '\xe7')},
  };
  for (const auto& [name, content] : variants) {
    write_bytes(dir / (name + ".pcd"), content);
    expect_unreadable(dir / (name + ".pcd"), name);
  }
  // Bit flips in the compressed stream: a scan of the right size or an InputError, never worse.
  std::mt19937 rng(1);
  std::uniform_int_distribution<size_t> pos(data + 8, bytes.size() - 1);
  write_bytes(dir / "flipped.pcd", bytes);
  for (int trial = 0; trial < 500; ++trial) {
    const size_t at = pos(rng);
    patch_byte(dir / "flipped.pcd", at, static_cast<char>(bytes[at] ^ (1 << (trial % 8))));
    try {
      EXPECT_EQ(read_pcd(dir / "flipped.pcd").points.size(), 2000u);
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), dir / "flipped.pcd");
    }
    patch_byte(dir / "flipped.pcd", at, bytes[at]);
  }
  fs::remove_all(dir);
}

TEST(CorruptScans, CorruptedScanGraphs) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  const AddressSpaceCap cap;
  const fs::path dir = testing::make_temp_dir("corrupt-graph");
  const std::string bytes = testing::read_bytes(datasets / "octomap_samples" / "spherical_scan.graph");
  const size_t pose_at = 8 + 28 * 10201;  // node 0's pose record
  auto with = [&](size_t at, const void* value, size_t n) {
    std::string b = bytes;
    std::memcpy(&b[at], value, n);
    return b;
  };
  const uint32_t huge = 0xffffffffu, one_more = 10202, one_less = 10200, two = 2, five = 5, bad_marker = 7;
  const double nan = std::numeric_limits<double>::quiet_NaN(), two_d = 2.0, big = 1e300;
  const std::map<std::string, std::string> variants = {
      {"absurd_node_count", with(0, &huge, 4)},
      {"two_nodes", with(0, &two, 4)},
      {"absurd_point_count", with(4, &huge, 4)},
      {"one_point_more", with(4, &one_more, 4)},
      {"one_point_less", with(4, &one_less, 4)},
      {"translation_marker", with(pose_at, &bad_marker, 4)},
      {"rotation_marker", with(pose_at + 28, &bad_marker, 4)},
      {"nan_translation", with(pose_at + 4, &nan, 8)},
      {"overflowing_translation", with(pose_at + 12, &big, 8)},
      {"non_unit_rotation", with(pose_at + 32, &two_d, 8)},
      {"edges_without_data", with(bytes.size() - 4, &five, 4)},
      {"trailing_bytes", bytes + std::string(3, '\0')},
      {"garbage", std::string(bytes.size(), '\x5a')},
      {"empty", ""},
  };
  for (const auto& [name, content] : variants) {
    write_bytes(dir / (name + ".graph"), content);
    expect_unreadable(dir / (name + ".graph"), name);
  }

  // An edge naming a node that is not there.
  {
    std::string with_edge = bytes.substr(0, bytes.size() - 4);
    const uint32_t edges = 1, first = 0, second = 9;
    with_edge.append(reinterpret_cast<const char*>(&edges), 4);
    with_edge.append(reinterpret_cast<const char*>(&first), 4).append(reinterpret_cast<const char*>(&second), 4);
    with_edge.append(bytes.substr(pose_at, 64)).append(8, '\0');
    write_bytes(dir / "dangling_edge.graph", with_edge);
    expect_unreadable(dir / "dangling_edge.graph", "dangling edge");
  }

  // Bit flips in the counts, the pose and the end: a well-formed scan or an InputError.
  std::vector<size_t> positions;
  for (size_t at = 0; at < 40; ++at) positions.push_back(at);
  for (size_t at = pose_at - 8; at < bytes.size(); ++at) positions.push_back(at);
  write_bytes(dir / "flipped.graph", bytes);
  for (size_t at : positions) {
    for (char mask : {'\x01', '\x80'}) {
      patch_byte(dir / "flipped.graph", at, static_cast<char>(bytes[at] ^ mask));
      try {
        const std::vector<Scan> scans = read_all_scans({dir / "flipped.graph"});
        ASSERT_EQ(scans.size(), 1u) << "byte " << at;
        EXPECT_EQ(scans[0].points.size(), 10201u) << "byte " << at;
      } catch (const InputError& e) {
        EXPECT_EQ(e.file(), dir / "flipped.graph");
      }
    }
    patch_byte(dir / "flipped.graph", at, bytes[at]);
  }
  fs::remove_all(dir);
}

TEST(CorruptScans, OtherFilesRenamedAsScans) {
  // Every shared file (maps included) under the wrong extension, and random bytes of each size.
  BGKMAP_REQUIRE_DATASETS(datasets);
  const AddressSpaceCap cap;
  const fs::path dir = testing::make_temp_dir("renamed");
  std::vector<fs::path> files;
  for (const char* ext : {".pcd", ".graph", ".bt"}) {
    const std::vector<fs::path> found = shared_files(datasets, ext);
    files.insert(files.end(), found.begin(), found.end());
  }
  ASSERT_EQ(files.size(), 15u);
  std::mt19937 rng(42);
  for (const fs::path& original : files) {
    const std::string bytes = testing::read_bytes(original);
    std::string noise(bytes.size(), '\0');
    for (char& c : noise) c = static_cast<char>(rng());
    for (const char* ext : {".pcd", ".graph"}) {
      if (original.extension() != ext) {
        const fs::path renamed = dir / (original.stem().string() + "_as" + ext);
        write_bytes(renamed, bytes);
        expect_unreadable(renamed, original.filename().string() + " as " + ext);
      }
      const fs::path random = dir / (original.stem().string() + "_noise" + ext);
      write_bytes(random, noise);
      expect_unreadable(random, "noise the size of " + original.filename().string());
    }
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap
