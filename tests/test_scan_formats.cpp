// The other scan formats through ScanSource: plain XYZ text, PLY (written by PCL, read through
// its reader), OctoMap's text scan log (poses checked against liboctomap's Pose6D) and KITTI
// odometry sequences (against Eigen's transforms); the PLY/XYZ poses from --poses / --origin; and
// every truncation of a small file and random byte flips give an InputError naming the file or a
// clean read, never a crash.
#include <gtest/gtest.h>
#include <octomap/math/Pose6D.h>
#include <pcl/io/ply_io.h>
#include <pcl/point_types.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/point_text_io.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

namespace fs = std::filesystem;
using testing::expect_input_error;
using testing::read_all_scans;
using testing::write_bytes;

class TempDir : public testing::TempDir {
 public:
  TempDir() : testing::TempDir("formats") {}
};

std::vector<Scan> read_with(const std::vector<fs::path>& inputs, const ScanSourceOptions& options) {
  ScanSource source(inputs, options);
  std::vector<Scan> scans;
  for (Scan scan; source.next(scan); scan = Scan{}) scans.push_back(scan);
  return scans;
}

void expect_near(const Vec3f& got, double x, double y, double z, double tol, const std::string& what) {
  EXPECT_NEAR(got.x, x, tol) << what;
  EXPECT_NEAR(got.y, y, tol) << what;
  EXPECT_NEAR(got.z, z, tol) << what;
}

// Every prefix of `bytes` as `file`, and `flips` copies with one random byte changed: each read
// is an InputError naming `file` in one line, or a clean read. `read` reads the inputs.
void sweep_corruptions(const fs::path& file, const std::string& bytes, int flips, const std::function<void()>& read,
                       const fs::path& named = {}) {
  const fs::path expected = named.empty() ? file : named;
  const auto check = [&](const std::string& context) {
    try {
      read();
    } catch (const InputError& e) {
      const std::string message = e.what();
      EXPECT_EQ(message.find('\n'), std::string::npos) << context << ": " << message;
      EXPECT_NE(message.find(expected.filename().string()), std::string::npos) << context << ": " << message;
    } catch (const std::exception& e) {
      ADD_FAILURE() << context << ": non-InputError " << e.what();
    }
  };
  for (size_t size = 0; size < bytes.size(); ++size) {
    write_bytes(file, bytes.substr(0, size));
    check("cut at " + std::to_string(size));
  }
  std::mt19937 rng(21);
  for (int i = 0; i < flips; ++i) {
    std::string bad = bytes;
    const size_t at = rng() % bad.size();
    bad[at] = static_cast<char>(bad[at] ^ (1 + rng() % 255));
    write_bytes(file, bad);
    check("flip at " + std::to_string(at));
  }
  write_bytes(file, bytes);
}

// ---------------------------------------------------------------- XYZ

TEST(XyzScans, PointsAndOriginFromTheFlagOrThePosesFile) {
  TempDir dir;
  write_bytes(dir / "a.xyz", "# x y z\n1 2 3\n\n4.5 -6 7e-1 0.3 extra\r\n// note\nnan 0 0\n");
  write_bytes(dir / "b.xyz", "0 0 1\n");
  const std::vector<Scan> scans = read_with({dir / "a.xyz", dir / "b.xyz"}, {{}, Vec3f{1, 1, 0}, {}, {}, {}});
  ASSERT_EQ(scans.size(), 2u);
  ASSERT_EQ(scans[0].points.size(), 3u);
  expect_near(scans[0].points[0], 1, 2, 3, 0, "a[0]");
  expect_near(scans[0].points[1], 4.5, -6, 0.7, 1e-7, "a[1]");
  EXPECT_TRUE(std::isnan(scans[0].points[2].x));
  expect_near(scans[0].pose.position, 1, 1, 0, 0, "origin");
  // A poses file (TUM, as bgkmap simulate writes): line i for the i-th PLY/XYZ input. Its second
  // pose turns the points, so whether they are world- or sensor-frame must be said (--frame).
  write_bytes(dir / "poses.txt", "# time x y z qx qy qz qw\n0 1 2 3 0 0 0 1\n0.1 -1 -2 -3 0 0 0.7071068 0.7071068\n");
  expect_input_error(dir / "poses.txt", [&] { read_with({dir / "a.xyz", dir / "b.xyz"}, {dir / "poses.txt", {}, {}, {}, {}}); },
                     "rotated pose, no frame");
  try {
    read_with({dir / "a.xyz", dir / "b.xyz"}, {dir / "poses.txt", {}, {}, {}, {}});
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("line 3: a rotated pose for " + (dir / "b.xyz").string()), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--frame world or --frame sensor"), std::string::npos) << e.what();
  }
  ScanSourceOptions world{dir / "poses.txt", {}, {}, {}, {}};
  world.frame = PointFrame::kWorld;
  const std::vector<Scan> posed = read_with({dir / "a.xyz", dir / "b.xyz"}, world);
  expect_near(posed[0].pose.position, 1, 2, 3, 0, "pose 0");
  expect_near(posed[1].pose.position, -1, -2, -3, 0, "pose 1");
  EXPECT_NEAR(posed[1].pose.qz, std::sqrt(0.5), 1e-6);
  // No origin, or a pose count that differs from the files: refused before reading.
  expect_input_error(dir / "a.xyz", [&] { read_with({dir / "a.xyz"}, {}); }, "no origin");
  expect_input_error(dir / "poses.txt", [&] { read_with({dir / "a.xyz"}, {dir / "poses.txt", {}, {}, {}, {}}); }, "2 poses, 1 file");
}

TEST(XyzScans, MalformedAndCorruptFilesAreCleanErrors) {
  TempDir dir;
  write_bytes(dir / "bad.xyz", "1 2 3\n1 2\n");
  expect_input_error(dir / "bad.xyz", [&] { read_xyz(dir / "bad.xyz"); }, "two fields");
  try {
    read_xyz(dir / "bad.xyz");
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("line 2: XYZ: 2 fields"), std::string::npos) << e.what();
  }
  const std::string text = "1 2 3\n-4.25 5 6.5\n7 8 9 10\n";
  sweep_corruptions(dir / "c.xyz", text, 200, [&] { read_xyz(dir / "c.xyz"); });
}

// ---------------------------------------------------------------- PLY

pcl::PointCloud<pcl::PointXYZ> sample_cloud() {
  pcl::PointCloud<pcl::PointXYZ> cloud;
  for (int i = 0; i < 6; ++i) cloud.push_back(pcl::PointXYZ(0.5f * i, -1.25f * i, 2.0f + i));
  return cloud;
}

TEST(PlyScans, AsciiAndBinaryFilesGiveTheirVertices) {
  TempDir dir;
  const pcl::PointCloud<pcl::PointXYZ> cloud = sample_cloud();
  ASSERT_EQ(pcl::io::savePLYFileASCII((dir / "a.ply").string(), cloud), 0);
  ASSERT_EQ(pcl::io::savePLYFileBinary((dir / "b.ply").string(), cloud), 0);
  for (const char* name : {"a.ply", "b.ply"}) {
    const std::vector<Scan> scans = read_with({dir / name}, {{}, Vec3f{0, 0, 1}, {}, {}, {}});
    ASSERT_EQ(scans.size(), 1u) << name;
    ASSERT_EQ(scans[0].points.size(), cloud.size()) << name;
    for (size_t i = 0; i < cloud.size(); ++i)
      expect_near(scans[0].points[i], cloud[i].x, cloud[i].y, cloud[i].z, 0, std::string(name) + " vertex " + std::to_string(i));
    expect_near(scans[0].pose.position, 0, 0, 1, 0, "origin");
  }
  // A hand-written header: double coordinates, another element, a list property.
  std::string text =
      "ply\nformat ascii 1.0\ncomment made by hand\nelement vertex 2\nproperty double x\nproperty double y\n"
      "property double z\nproperty uchar red\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
      "1.5 2.5 3.5 255\n-1 -2 -3 0\n3 0 1 1\n";
  write_bytes(dir / "c.ply", text);
  const Scan c = read_ply(dir / "c.ply");
  ASSERT_EQ(c.points.size(), 2u);
  expect_near(c.points[1], -1, -2, -3, 0, "double vertex");
}

TEST(PlyScans, BadHeadersAndCorruptFilesAreCleanErrors) {
  TempDir dir;
  const std::string head = "ply\nformat binary_little_endian 1.0\nelement vertex ";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {head + "99999999999\nproperty float x\nproperty float y\nproperty float z\nend_header\n", "claims 99999999999"},
      {head + "1\nproperty float x\nproperty float y\nend_header\n", "no 'z' property"},
      {head + "1\nproperty int x\nproperty float y\nproperty float z\nend_header\n", "'x' is not float"},
      {"ply\nformat weird 1.0\nend_header\n", "unknown format"},
      {"PLY\n", "no 'ply' magic"},
      {head + "1\nproperty float x\nproperty float y\nproperty float z\n", "no end_header"},
      {head + "2\nproperty float x\nproperty float y\nproperty float z\nend_header\n" + std::string(12, '\0'), "claims 2 items, the file has 12 bytes"},
      // Found by fuzz_ply: lists of different lengths in the vertex element made PCL abort.
      {"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
       "property list uchar int vertex_indices\nend_header\n1 2 3 1 7\n1 2 3 2 7 8\n",
       "the vertex element has a list property 'vertex_indices' (not supported)"},
      {head + "2\nproperty float x\nproperty float y\nproperty float z\nproperty list uchar int vertex_indices\n"
       "end_header\n" + std::string(12, '\0') + '\1' + std::string(4, '\0') + std::string(12, '\0') + '\2' +
       std::string(8, '\0'),
       "the vertex element has a list property 'vertex_indices' (not supported)"},
  };
  for (const auto& [bytes, expected] : cases) {
    write_bytes(dir / "bad.ply", bytes);
    expect_input_error(dir / "bad.ply", [&] { read_ply(dir / "bad.ply"); }, expected);
    try {
      read_ply(dir / "bad.ply");
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
    }
  }
  const pcl::PointCloud<pcl::PointXYZ> cloud = sample_cloud();
  for (bool binary : {true, false}) {
    SCOPED_TRACE(binary ? "binary" : "ascii");
    const fs::path file = dir / "s.ply";
    ASSERT_EQ(binary ? pcl::io::savePLYFileBinary(file.string(), cloud) : pcl::io::savePLYFileASCII(file.string(), cloud), 0);
    const std::string bytes = testing::read_bytes(file);
    // Every truncation of a binary file is an error (the body size is checked).
    if (binary)
      for (size_t size = 0; size < bytes.size(); ++size) {
        write_bytes(file, bytes.substr(0, size));
        expect_input_error(file, [&] { read_ply(file); }, "cut at " + std::to_string(size));
      }
    sweep_corruptions(file, bytes, 200, [&] { read_ply(file); });
  }
}

// ---------------------------------------------------------------- OctoMap text log

const char* const kOctomapLog =
    "# scan log\n"
    "NODE 1 2 0.5 0 0 1.5707963\n"
    "1 0 0\n"
    "0 2 0.25\n"
    "NODE -1 0 0 0.3 -0.2 0.1\n"
    "\n"
    "2 1 -1\n"
    "NODE 0 0 0 0 0 0\n";

TEST(OctomapLog, NodesGiveWorldFramePointsByOctomapsPose6D) {
  TempDir dir;
  write_bytes(dir / "scan.dat", kOctomapLog);
  write_bytes(dir / "scan.log", kOctomapLog);  // a .log starting with NODE is an OctoMap log
  EXPECT_EQ(scan_file_type(dir / "scan.log"), ScanFileType::kOctomapLog);
  for (const char* name : {"scan.dat", "scan.log"}) {
    SCOPED_TRACE(name);
    const std::vector<Scan> scans = read_all_scans({dir / name});
    ASSERT_EQ(scans.size(), 3u);
    const std::vector<std::vector<octomath::Vector3>> local = {{{1, 0, 0}, {0, 2, 0.25}}, {{2, 1, -1}}, {}};
    const octomath::Pose6D poses[] = {{1, 2, 0.5, 0, 0, 1.5707963}, {-1, 0, 0, 0.3, -0.2, 0.1}, {0, 0, 0, 0, 0, 0}};
    for (size_t s = 0; s < 3; ++s) {
      ASSERT_EQ(scans[s].points.size(), local[s].size());
      EXPECT_TRUE(scans[s].points_in_world_frame);
      const octomath::Vector3& t = poses[s].trans();
      expect_near(scans[s].pose.position, t.x(), t.y(), t.z(), 1e-6, "origin");
      for (size_t i = 0; i < local[s].size(); ++i) {
        const octomath::Vector3 w = poses[s].transform(local[s][i]);
        expect_near(scans[s].points[i], w.x(), w.y(), w.z(), 1e-5, "node " + std::to_string(s) + " point " + std::to_string(i));
      }
    }
  }
}

TEST(OctomapLog, MalformedAndCorruptLogsAreCleanErrors) {
  TempDir dir;
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"1 2 3\nNODE 0 0 0 0 0 0\n", "line 1: points before the first NODE"},
      {"NODE 0 0 0 0 0\n", "line 1: NODE: 5 values"},
      {"NODE 0 0 inf 0 0 0\n", "line 1: NODE: value 3 is not a finite number"},
      {"NODE 0 0 0 0 0 0\n1 2\n", "line 2: point: 2 fields"},
      {"NODE 0 0 0 0 0 0\n1 2 x\n", "line 2: point: field 3"},
  };
  for (const auto& [text, expected] : cases) {
    write_bytes(dir / "bad.dat", text);
    expect_input_error(dir / "bad.dat", [&] { read_all_scans({dir / "bad.dat"}); }, expected);
    try {
      read_all_scans({dir / "bad.dat"});
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
    }
  }
  sweep_corruptions(dir / "c.dat", kOctomapLog, 300, [&] { read_all_scans({dir / "c.dat"}); });
}

// ---------------------------------------------------------------- KITTI

struct KittiFixture {
  Eigen::Matrix4d tr = Eigen::Matrix4d::Identity();
  std::vector<Eigen::Matrix4d> poses;
  std::vector<std::vector<Eigen::Vector3d>> points;
};

std::string matrix_text(const Eigen::Matrix4d& m) {
  std::string s;
  char buf[40];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) {
      std::snprintf(buf, sizeof buf, "%s%.17g", s.empty() ? "" : " ", m(r, c));
      s += buf;
    }
  return s;
}

Eigen::Matrix4d rigid(double angle, const Eigen::Vector3d& axis, const Eigen::Vector3d& t) {
  Eigen::Affine3d a = Eigen::Translation3d(t) * Eigen::AngleAxisd(angle, axis.normalized());
  return a.matrix();
}

// A two-scan sequence with a non-trivial Tr and poses.
KittiFixture write_kitti(const fs::path& seq) {
  KittiFixture k;
  k.tr = rigid(0.4, {1, -2, 0.5}, {0.1, -0.2, 0.3});
  k.poses = {rigid(0.0, {0, 0, 1}, {0, 0, 0}), rigid(-0.7, {0.2, 1, 0.1}, {1.5, -0.25, 4})};
  k.points = {{{1, 2, 3}, {-4, 0.5, 0}}, {{10, -1, 0.25}}};
  fs::create_directories(seq / "velodyne");
  write_bytes(seq / "calib.txt", "P0: 1 0 0 0 0 1 0 0 0 0 1 0\nTr: " + matrix_text(k.tr) + "\n");
  write_bytes(seq / "poses.txt", matrix_text(k.poses[0]) + "\n" + matrix_text(k.poses[1]) + "\n");
  for (size_t s = 0; s < k.points.size(); ++s) {
    std::string bytes;
    for (const Eigen::Vector3d& p : k.points[s]) {
      const float v[4] = {float(p.x()), float(p.y()), float(p.z()), 0.5f};
      bytes.append(reinterpret_cast<const char*>(v), sizeof v);
    }
    char name[32];
    std::snprintf(name, sizeof name, "%06zu.bin", s);
    write_bytes(seq / "velodyne" / name, bytes);
  }
  return k;
}

// By default the world is the velodyne frame of the first scan: (P_0 Tr)^-1 P_i Tr p; on request
// KITTI's camera frame: P_i Tr p.
TEST(KittiSequence, ScansInTheVelodyneFrameOfTheFirstScanOrInTheCameraFrame) {
  TempDir dir;
  const fs::path seq = dir / "08";
  const KittiFixture k = write_kitti(seq);
  EXPECT_EQ(scan_file_type(seq), ScanFileType::kKittiSequence);
  for (const KittiFrame frame : {KittiFrame::kVelodyne, KittiFrame::kCamera}) {
    ScanSourceOptions options;
    options.kitti_frame = frame;
    const std::vector<Scan> scans = read_with({seq}, options);
    ASSERT_EQ(scans.size(), 2u);
    const Eigen::Matrix4d world = frame == KittiFrame::kVelodyne ? Eigen::Matrix4d((k.poses[0] * k.tr).inverse())
                                                                 : Eigen::Matrix4d::Identity();
    for (size_t s = 0; s < 2; ++s) {
      const Eigen::Matrix4d m = world * k.poses[s] * k.tr;
      expect_near(scans[s].pose.position, m(0, 3), m(1, 3), m(2, 3), 1e-6, "origin");
      const Eigen::Quaterniond q(Eigen::Matrix3d(m.block<3, 3>(0, 0)));
      EXPECT_NEAR(std::abs(q.w() * scans[s].pose.qw + q.x() * scans[s].pose.qx + q.y() * scans[s].pose.qy +
                           q.z() * scans[s].pose.qz),
                  1.0, 1e-6);
      ASSERT_EQ(scans[s].points.size(), k.points[s].size());
      for (size_t i = 0; i < k.points[s].size(); ++i) {
        const Eigen::Vector3d w = (m * k.points[s][i].homogeneous()).head<3>();
        expect_near(scans[s].points[i], w.x(), w.y(), w.z(), 1e-5, "point");
      }
    }
    if (frame == KittiFrame::kVelodyne) {  // the first scan at the origin, unturned
      expect_near(scans[0].pose.position, 0, 0, 0, 1e-12, "first origin");
      EXPECT_NEAR(std::abs(scans[0].pose.qw), 1.0, 1e-7);
    }
  }
}

TEST(KittiSequence, MissingCountsAndCorruptFilesAreCleanErrors) {
  TempDir dir;
  const fs::path seq = dir / "00";
  write_kitti(seq);
  const std::string poses = testing::read_bytes(seq / "poses.txt");
  write_bytes(seq / "poses.txt", poses.substr(0, poses.find('\n') + 1));
  expect_input_error(seq / "poses.txt", [&] { read_all_scans({seq}); }, "1 pose for 2 scans");
  write_bytes(seq / "poses.txt", poses);
  const std::string calib = testing::read_bytes(seq / "calib.txt");
  write_bytes(seq / "calib.txt", "P0: 1 0 0 0 0 1 0 0 0 0 1 0\n");
  expect_input_error(seq / "calib.txt", [&] { read_all_scans({seq}); }, "no Tr");
  write_bytes(seq / "calib.txt", calib);
  const auto read = [&] { read_all_scans({seq}); };
  sweep_corruptions(seq / "velodyne" / "000000.bin", testing::read_bytes(seq / "velodyne" / "000000.bin"), 100, read);
  sweep_corruptions(seq / "poses.txt", poses, 200, read);
  sweep_corruptions(seq / "calib.txt", calib, 200, read);
}

}  // namespace
}  // namespace bgkmap
