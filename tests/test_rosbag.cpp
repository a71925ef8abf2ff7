// ROS 1 bags as input: bags written here with rosbag::Bag from bgkmap simulate's scans give the
// maps their PCD files give; tf lookups, LaserScan conventions, refusals, resume and corrupt bags.
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <sensor_msgs/LaserScan.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/Header.h>
#include <tf2_msgs/TFMessage.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <tuple>
#include <vector>

#include "bgkmap/io/native_map.hpp"
#include "bgkmap/io/pcd_io.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "bgkmap/map/bgk_map.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

using Result = testing::CommandResult;
using Rigid = Eigen::Isometry3d;

Result run(const std::string& args) { return testing::run_command(std::string(BGKMAP_CLI) + " " + args); }

size_t lines_of(const std::string& text) { return static_cast<size_t>(std::count(text.begin(), text.end(), '\n')); }

nlohmann::json read_json(const std::filesystem::path& file) {
  std::ifstream in(file);
  return nlohmann::json::parse(in);
}

Rigid rigid_of(const Pose& p) {
  Rigid r = Rigid::Identity();
  r.linear() = Eigen::Quaterniond(p.qw, p.qx, p.qy, p.qz).normalized().toRotationMatrix();
  r.translation() = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
  return r;
}

geometry_msgs::TransformStamped transform_msg(const std::string& parent, const std::string& child, ros::Time stamp,
                                              const Rigid& r) {
  geometry_msgs::TransformStamped t;
  t.header.frame_id = parent;
  t.header.stamp = stamp;
  t.child_frame_id = child;
  const Eigen::Quaterniond q(r.linear());
  t.transform.rotation.w = q.w(), t.transform.rotation.x = q.x(), t.transform.rotation.y = q.y(), t.transform.rotation.z = q.z();
  t.transform.translation.x = r.translation().x(), t.transform.translation.y = r.translation().y();
  t.transform.translation.z = r.translation().z();
  return t;
}

void write_tf(rosbag::Bag& bag, const std::string& topic, const geometry_msgs::TransformStamped& t) {
  tf2_msgs::TFMessage msg;
  msg.transforms.push_back(t);
  bag.write(topic, t.header.stamp, msg);
}

// A cloud of x, y, z float32 with an intensity field between them: point_step 20, x at offset 8,
// and `row_padding` bytes after each row.
sensor_msgs::PointCloud2 cloud_msg(const std::string& frame, ros::Time stamp, const std::vector<Eigen::Vector3f>& points,
                                   uint32_t height = 1, uint32_t row_padding = 4) {
  sensor_msgs::PointCloud2 c;
  c.header.frame_id = frame;
  c.header.stamp = stamp;
  c.height = height;
  c.width = static_cast<uint32_t>(points.size() / height);
  const std::pair<const char*, uint32_t> fields[] = {{"y", 0}, {"z", 4}, {"x", 8}, {"intensity", 12}};
  for (const auto& [name, offset] : fields) {
    sensor_msgs::PointField f;
    f.name = name;
    f.offset = offset;
    f.datatype = sensor_msgs::PointField::FLOAT32;
    f.count = 1;
    c.fields.push_back(f);
  }
  c.point_step = 20;
  c.row_step = c.width * c.point_step + row_padding;
  c.data.assign(size_t(c.row_step) * c.height, 0xAB);
  for (uint32_t v = 0; v < c.height; ++v)
    for (uint32_t u = 0; u < c.width; ++u) {
      const Eigen::Vector3f& p = points[v * c.width + u];
      uint8_t* at = c.data.data() + size_t(v) * c.row_step + size_t(u) * c.point_step;
      std::memcpy(at + 0, &p.y(), 4);
      std::memcpy(at + 4, &p.z(), 4);
      std::memcpy(at + 8, &p.x(), 4);
    }
  return c;
}

std::vector<Eigen::Vector3f> to_sensor_frame(const Scan& scan, const Rigid& world_from_sensor) {
  std::vector<Eigen::Vector3f> out;
  for (const Vec3f& p : scan.points)
    out.push_back((world_from_sensor.inverse() * Eigen::Vector3d(p.x, p.y, p.z)).cast<float>());
  return out;
}

using CellKey = std::tuple<int32_t, int32_t, int32_t>;
std::map<CellKey, CellPosterior> cells_of(const std::filesystem::path& map_file) {
  const BgkMap map = read_native_map(map_file);
  std::map<CellKey, CellPosterior> cells;
  map.for_each_cell_with_evidence([&](const CellIndex& c, const CellPosterior& p) { cells[{c.x, c.y, c.z}] = p; });
  return cells;
}

// The same cells, each alpha and beta within `relative` of the other map's (and 1e-9 absolute, for
// the prior's 0.001 next to nothing).
void expect_same_cells(const std::filesystem::path& a_file, const std::filesystem::path& b_file, double relative) {
  const auto a = cells_of(a_file), b = cells_of(b_file);
  ASSERT_GT(a.size(), 1000u);
  ASSERT_EQ(a.size(), b.size());
  double worst = 0;
  for (const auto& [key, pa] : a) {
    const auto found = b.find(key);
    ASSERT_NE(found, b.end()) << std::get<0>(key) << " " << std::get<1>(key) << " " << std::get<2>(key);
    const CellPosterior& pb = found->second;
    for (const auto& [x, y] : {std::pair{pa.alpha, pb.alpha}, std::pair{pa.beta, pb.beta}}) {
      const double d = std::abs(x - y), scale = std::max(std::abs(x), std::abs(y));
      if (d > 1e-9) worst = std::max(worst, d / scale);
    }
  }
  EXPECT_LE(worst, relative);
  std::printf("largest relative difference of alpha/beta between %s and %s: %.3g over %zu cells\n",
              a_file.filename().c_str(), b_file.filename().c_str(), worst, a.size());
}

class Rosbags : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new testing::TempDir("rosbag");
    const Result vlp = run("simulate structured -q --scans 3 --truth-resolution 0 -o " + (*dir_ / "sim").string());
    ASSERT_EQ(vlp.status, 0) << vlp.output;
    const Result planar =
        run("simulate structured -q --sensor planar --scans 3 --truth-resolution 0 -o " + (*dir_ / "planar").string());
    ASSERT_EQ(planar.status, 0) << planar.output;
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static std::string path(const std::string& name) { return (*dir_ / name).string(); }
  static std::vector<Scan> sim_scans(const std::string& which) {
    std::vector<Scan> scans;
    for (int i = 0; i < 3; ++i) scans.push_back(read_pcd(*dir_ / which / "scans" / scan_name(i)));
    return scans;
  }
  static std::string scan_name(int i) { return "scan_0000" + std::to_string(i) + ".pcd"; }

  // The simulated scans as PointCloud2 in frame "velodyne", mounted on "base_link" by a fixed
  // /tf_static transform; /tf gives map <- base_link at each scan's stamp, 100 + i s, and
  // `extra_nan` adds a NaN point to each cloud.
  static void write_cloud_bag(const std::filesystem::path& file, const std::vector<Scan>& scans, size_t first = 0,
                              size_t count = 3) {
    rosbag::Bag bag(file.string(), rosbag::bagmode::Write);
    Rigid base_from_velodyne = Rigid::Identity();
    base_from_velodyne.linear() = (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()) *
                                   Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitY())).toRotationMatrix();
    base_from_velodyne.translation() = Eigen::Vector3d(0.1, -0.05, 0.4);
    write_tf(bag, "/tf_static", transform_msg("base_link", "velodyne", ros::Time(99, 0), base_from_velodyne));
    for (size_t i = first; i < first + count; ++i) {
      const ros::Time stamp(100 + static_cast<uint32_t>(i), 0);
      const Rigid world_from_sensor = rigid_of(scans[i].pose);
      write_tf(bag, "/tf", transform_msg("map", "base_link", stamp, world_from_sensor * base_from_velodyne.inverse()));
      std::vector<Eigen::Vector3f> points = to_sensor_frame(scans[i], world_from_sensor);
      points.push_back(Eigen::Vector3f::Constant(std::numeric_limits<float>::quiet_NaN()));
      bag.write("/points", stamp, cloud_msg("velodyne", stamp, points));
    }
  }

  static testing::TempDir* dir_;
};
testing::TempDir* Rosbags::dir_ = nullptr;

const std::string kBuildFlags = " -q --backend cpu --threads 2 --max-range 8 --resolution 0.1 --ell 0.2";

// PointCloud2 + /tf of simulate's scans against the PCD folder: the same cells, alpha and beta to a
// relative 1e-4 (2.4e-5 measured; the bag stores sensor-frame floats, so each point comes back rounded differently).
TEST_F(Rosbags, PointCloudBagWithTfGivesThePcdFoldersMap) {
  const std::vector<Scan> scans = sim_scans("sim");
  write_cloud_bag(path("points.bag"), scans);
  Result r = run("build " + path("sim/scans") + " -o " + path("pcd.bgk") + kBuildFlags + " --report " + path("pcd.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  r = run("build " + path("points.bag") + " --topic /points --tf-frame map -o " + path("bag.bgk") + kBuildFlags +
          " --report " + path("bag.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  expect_same_cells(path("pcd.bgk"), path("bag.bgk"), 1e-4);

  const nlohmann::json pcd = read_json(path("pcd.json"))["counts"], bag = read_json(path("bag.json"))["counts"];
  EXPECT_EQ(bag["scans"], 3);
  EXPECT_EQ(bag["points_read"].get<uint64_t>(), pcd["points_read"].get<uint64_t>() + 3);  // a NaN point a cloud
  EXPECT_EQ(bag["dropped_nonfinite"].get<uint64_t>(), pcd["dropped_nonfinite"].get<uint64_t>() + 3);
  EXPECT_EQ(bag["hits"], pcd["hits"]);
  EXPECT_EQ(bag["beams"], pcd["beams"]);
  EXPECT_EQ(bag["skipped_messages"]["tf2_msgs/TFMessage"], 4);  // three /tf and one /tf_static
  const nlohmann::json params = read_json(path("bag.json"))["params"];
  EXPECT_EQ(params["topics"], nlohmann::json::array({"/points"}));
  EXPECT_EQ(params["tf_frame"], "map");
}

// Poses from --poses: a bag whose clouds are in the sensor frame the poses give, against the PCDs.
TEST_F(Rosbags, PosesFileGivesOnePoseAMessage) {
  const std::vector<Scan> scans = sim_scans("sim");
  {
    rosbag::Bag bag(path("plain.bag"), rosbag::bagmode::Write);
    for (size_t i = 0; i < scans.size(); ++i) {
      const ros::Time stamp(100 + static_cast<uint32_t>(i), 0);
      bag.write("/points", stamp, cloud_msg("velodyne", stamp, to_sensor_frame(scans[i], rigid_of(scans[i].pose))));
    }
  }
  Result r = run("build " + path("sim/scans") + " -o " + path("pcd2.bgk") + kBuildFlags);
  ASSERT_EQ(r.status, 0) << r.output;
  r = run("build " + path("plain.bag") + " --topic /points --poses " + path("sim/poses.txt") + " -o " +
          path("bag2.bgk") + kBuildFlags);
  ASSERT_EQ(r.status, 0) << r.output;
  expect_same_cells(path("pcd2.bgk"), path("bag2.bgk"), 1e-4);

  // A poses file of another length is refused, naming it and the message count.
  std::ofstream(path("two_poses.txt")) << "0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n";
  r = run("build " + path("plain.bag") + " --topic /points --poses " + path("two_poses.txt") + " -o " + path("x.bgk") + " -q");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_EQ(lines_of(r.output), 1u) << r.output;
  EXPECT_NE(r.output.find("two_poses.txt: 2 poses for 3 messages of the bags' --topic (one pose a message, in bag time order)"),
            std::string::npos) << r.output;
  // No pose source at all: refused, naming both flags.
  r = run("build " + path("plain.bag") + " --topic /points -o " + path("x.bgk") + " -q");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_EQ(lines_of(r.output), 1u) << r.output;
  EXPECT_NE(r.output.find("plain.bag: a ROS bag's messages need poses: give --tf-frame FRAME"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--poses FILE"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(path("x.bgk")));
  // The pose rule: a bag posed by /tf has a pose of its own, so --poses beside it is refused; a
  // bag's lines are one a message, so --poses serves bags alone.
  r = run("build " + path("plain.bag") + " --topic /points --tf-frame map --poses " + path("sim/poses.txt") + " -o " +
          path("x.bgk") + " -q");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("plain.bag: has a sensor pose of its own (/tf in --tf-frame) and --poses gives one too"),
            std::string::npos) << r.output;
  r = run("build " + path("plain.bag") + " " + path("sim/scans") + " --topic /points --poses " + path("sim/poses.txt") +
          " -o " + path("x.bgk") + " -q");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("poses.txt: gives other inputs one pose a file, but a ROS bag one a message"), std::string::npos)
      << r.output;
  // --topic without a bag is a mistake, not something to ignore.
  r = run("build " + path("sim/scans") + " --topic /points -o " + path("x.bgk") + " -q");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("--topic and --tf-frame are for ROS bag inputs (.bag), and none is given"), std::string::npos)
      << r.output;
}

// A planar laser's scans as LaserScan messages against the same scans as PCD files, both with --2d
// and --max-range 6: the bag's laser reaches 6 m (range_max; the scene's walls are up to 8.5 m
// away), so its readings beyond are +inf, no returns, and make the same free beams as the PCD's
// returns beyond --max-range.
TEST_F(Rosbags, LaserScanBagGivesThePlanarPcdMap) {
  const std::vector<Scan> scans = sim_scans("planar");
  const double range_max = 6;
  uint64_t no_returns = 0;
  {
    rosbag::Bag bag(path("scan.bag"), rosbag::bagmode::Write);
    for (size_t i = 0; i < scans.size(); ++i) {
      const ros::Time stamp(200 + static_cast<uint32_t>(i), 500000000);
      const Rigid world_from_laser = rigid_of(scans[i].pose);
      write_tf(bag, "/tf", transform_msg("odom", "laser", stamp, world_from_laser));
      const std::vector<Eigen::Vector3f> points = to_sensor_frame(scans[i], world_from_laser);
      sensor_msgs::LaserScan laser;
      laser.header.frame_id = "laser";
      laser.header.stamp = stamp;
      const double first = std::atan2(points.front().y(), points.front().x());
      const double last = std::atan2(points.back().y(), points.back().x());
      laser.angle_min = static_cast<float>(first);
      laser.angle_increment = static_cast<float>((last - first) / double(points.size() - 1));
      laser.angle_max = static_cast<float>(last);
      laser.range_min = 0.05f;
      laser.range_max = static_cast<float>(range_max);
      for (size_t k = 0; k < points.size(); ++k) {
        const double r = points[k].cast<double>().norm();
        // The bag must describe the same beams: each within 0.1 mm of its direction.
        const double a = double(laser.angle_min) + double(k) * double(laser.angle_increment);
        ASSERT_LT((points[k].cast<double>() - r * Eigen::Vector3d(std::cos(a), std::sin(a), 0)).norm(), 1e-4) << k;
        const bool none = r >= range_max;
        no_returns += none;
        laser.ranges.push_back(none ? std::numeric_limits<float>::infinity() : static_cast<float>(r));
      }
      bag.write("/scan", stamp, laser);
    }
  }
  ASSERT_GT(no_returns, 0u);
  const std::string flags = " -q --backend cpu --threads 2 --max-range 6 --resolution 0.1 --ell 0.2 --2d --plane-z " +
                            std::to_string(scans.front().pose.position.z);
  Result r = run("build " + path("planar/scans") + " -o " + path("planar_pcd.bgk") + flags + " --report " +
                 path("planar_pcd.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  r = run("build " + path("scan.bag") + " --topic /scan --tf-frame odom -o " + path("planar_bag.bgk") + flags +
          " --report " + path("planar_bag.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  expect_same_cells(path("planar_pcd.bgk"), path("planar_bag.bgk"), 1e-4);
  const nlohmann::json pcd = read_json(path("planar_pcd.json"))["counts"], bag = read_json(path("planar_bag.json"))["counts"];
  EXPECT_EQ(bag["no_returns"].get<uint64_t>(), no_returns);
  EXPECT_EQ(bag["beyond_max_range"].get<uint64_t>(), no_returns);  // as free beams of 6 m
  EXPECT_EQ(pcd["beyond_max_range"].get<uint64_t>(), no_returns);
  EXPECT_EQ(bag["hits"], pcd["hits"]);
}

ScanSourceOptions tf_options(const std::vector<std::string>& topics, const std::string& frame) {
  ScanSourceOptions o;
  o.topics = topics;
  o.tf_frame = frame;
  return o;
}

// tf: interpolated between two stamps, composed through a static mount, leading slashes dropped;
// LaserScan: range_min, range_max, inf and NaN readings.
TEST(RosbagReader, LooksPosesUpInTfAndKeepsLaserScanConventions) {
  testing::TempDir dir("rosbag_tf");
  const std::filesystem::path file = dir / "tf.bag";
  {
    rosbag::Bag bag(file.string(), rosbag::bagmode::Write);
    Rigid at10 = Rigid::Identity(), at12 = Rigid::Identity(), mount = Rigid::Identity();
    at12.translation() = Eigen::Vector3d(2, 4, 0);
    at12.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    mount.translation() = Eigen::Vector3d(0, 0, 0.5);
    write_tf(bag, "/tf_static", transform_msg("/base", "/laser", ros::Time(1, 0), mount));
    write_tf(bag, "/tf", transform_msg("/map", "/base", ros::Time(10, 0), at10));
    write_tf(bag, "/tf", transform_msg("/map", "/base", ros::Time(12, 0), at12));
    sensor_msgs::LaserScan laser;
    laser.header.frame_id = "laser";
    laser.header.stamp = ros::Time(11, 0);
    laser.angle_min = 0;
    laser.angle_increment = static_cast<float>(M_PI / 2);
    laser.range_min = 0.1f;
    laser.range_max = 30;
    const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
    laser.ranges = {1.0f, 0.05f, inf, 40.0f, nan, 30.0f};
    bag.write("/scan", ros::Time(11, 0), laser);  // written before the /tf at 12 s it needs, by time
  }
  ScanSource source({file}, tf_options({"/scan"}, "map"));
  Scan scan;
  ASSERT_TRUE(source.next(scan));
  // Halfway: translation (1, 2, 0) and yaw 0.2 (tf's slerp), then the mount's 0.5 m up.
  const double yaw = 0.2;
  EXPECT_NEAR(scan.pose.position.x, 1, 1e-6);
  EXPECT_NEAR(scan.pose.position.y, 2, 1e-6);
  EXPECT_NEAR(scan.pose.position.z, 0.5, 1e-6);
  EXPECT_NEAR(scan.pose.qz, std::sin(yaw / 2), 1e-6);
  EXPECT_FLOAT_EQ(scan.no_return_range_m, 30.0f);
  EXPECT_TRUE(scan.points_in_world_frame);
  ASSERT_EQ(scan.points.size(), 6u);
  auto beam = [&](int i, double r) {
    const double a = yaw + i * M_PI / 2;
    return Eigen::Vector3d(1 + r * std::cos(a), 2 + r * std::sin(a), 0.5);
  };
  auto at = [&](int i) { return Eigen::Vector3d(scan.points[i].x, scan.points[i].y, scan.points[i].z); };
  EXPECT_LT((at(0) - beam(0, 1.0)).norm(), 1e-5);
  EXPECT_TRUE(std::isnan(scan.points[1].x));              // below range_min: no measurement
  EXPECT_LT((at(2) - beam(2, 30.003)).norm(), 1e-4);      // inf: a no return along its beam
  EXPECT_LT((at(3) - beam(3, 40.004)).norm(), 1e-4);      // beyond range_max: a no return, kept
  EXPECT_TRUE(std::isnan(scan.points[4].x));              // NaN
  EXPECT_LT((at(5) - beam(5, 30.003)).norm(), 1e-4);      // at range_max: a no return
  for (int i : {2, 3, 5}) EXPECT_GE((at(i) - beam(0, 0)).norm(), 30.0) << i;
  EXPECT_FALSE(source.next(scan));
}

// Any point_step and row_step, two rows, x after y and z: each point the reference transform of
// its sensor-frame point.
TEST(RosbagReader, ReadsPointCloud2LayoutsThroughTheirFields) {
  testing::TempDir dir("rosbag_layout");
  const std::filesystem::path file = dir / "layout.bag";
  Rigid pose = Rigid::Identity();
  pose.linear() = (Eigen::AngleAxisd(1.1, Eigen::Vector3d(1, 2, 3).normalized())).toRotationMatrix();
  pose.translation() = Eigen::Vector3d(5, -3, 2);
  const std::vector<Eigen::Vector3f> points = {{1, 0, 0}, {0, 2, 0}, {0, 0, 3}, {1, 2, 3}, {-4, 5, -6}, {0.5f, 0.25f, 8}};
  {
    rosbag::Bag bag(file.string(), rosbag::bagmode::Write);
    bag.setCompression(rosbag::compression::LZ4);
    write_tf(bag, "/tf_static", transform_msg("world", "cam", ros::Time(1, 0), pose));
    bag.write("/cloud", ros::Time(3, 0), cloud_msg("cam", ros::Time(3, 0), points, 2, 12));
  }
  ScanSource source({file}, tf_options({"/cloud"}, "world"));
  Scan scan;
  ASSERT_TRUE(source.next(scan));
  ASSERT_EQ(scan.points.size(), points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d want = pose * points[i].cast<double>();
    EXPECT_LT((Eigen::Vector3d(scan.points[i].x, scan.points[i].y, scan.points[i].z) - want).norm(), 1e-5) << i;
  }
  EXPECT_NEAR(scan.pose.position.x, 5, 1e-6);
  EXPECT_FALSE(source.next(scan));
}

// A message whose pose is not in /tf is refused in one line naming the bag, topic, time and flags;
// --skip-bad-inputs passes over it (and a big-endian cloud) and maps the rest of the bag.
TEST(RosbagCli, RefusesOrSkipsMessagesThatCannotBeMapped) {
  testing::TempDir dir("rosbag_cli");
  const std::filesystem::path file = dir / "gaps.bag";
  const std::vector<Eigen::Vector3f> points = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 0}};
  {
    rosbag::Bag bag(file.string(), rosbag::bagmode::Write);
    write_tf(bag, "/tf", transform_msg("map", "lidar", ros::Time(1, 0), Rigid::Identity()));
    write_tf(bag, "/tf", transform_msg("map", "lidar", ros::Time(2, 0), Rigid::Identity()));
    bag.write("/points", ros::Time(1, 0), cloud_msg("lidar", ros::Time(1, 0), points));
    bag.write("/points", ros::Time(5, 0), cloud_msg("lidar", ros::Time(5, 250000000), points));  // after the last tf
    sensor_msgs::PointCloud2 big = cloud_msg("lidar", ros::Time(2, 0), points);
    big.is_bigendian = true;
    bag.write("/points", ros::Time(6, 0), big);
    bag.write("/points", ros::Time(7, 0), cloud_msg("lidar", ros::Time(2, 0), points));
    bag.write("/imu", ros::Time(7, 0), std_msgs::Header());
  }
  const std::string bag = file.string(), out = (dir / "m.bgk").string(), report = (dir / "r.json").string();
  Result r = run("build -q " + bag + " --topic /points --tf-frame map -o " + out);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_EQ(lines_of(r.output), 1u) << r.output;
  EXPECT_NE(r.output.find(bag + ": /points at bag time 5.000000000 (message 2 of the --topic messages): no transform map <- lidar at "
                          "5.250000000"),
            std::string::npos) << r.output;
  for (const char* flag : {"--tf-frame", "--poses", "--skip-bad-inputs"}) EXPECT_NE(r.output.find(flag), std::string::npos) << flag;
  EXPECT_FALSE(std::filesystem::exists(out));

  r = run("build -q " + bag + " --topic /points --tf-frame map --skip-bad-inputs -o " + out + " --report " + report);
  ASSERT_EQ(r.status, 0) << r.output;
  const nlohmann::json j = read_json(report);
  EXPECT_EQ(j["counts"]["scans"], 2);
  EXPECT_EQ(j["counts"]["inputs_skipped"], 2);
  EXPECT_NE(j["skipped_inputs"][1]["error"].get<std::string>().find("big-endian PointCloud2 (is_bigendian)"), std::string::npos);
  EXPECT_EQ(j["counts"]["skipped_messages"]["tf2_msgs/TFMessage"], 2);
  EXPECT_EQ(j["counts"]["skipped_messages"]["std_msgs/Header"], 1);
  // tf1's "/map" names the same frame.
  r = run("build -q " + bag + " --topic /points --tf-frame /map --skip-bad-inputs -o " + out + " --report " + report);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(read_json(report)["counts"]["scans"], 2);

  // A topic the bag lacks, or one of another type: refused before any work, naming the topics.
  r = run("build -q " + bag + " --topic /velodyne_points --tf-frame map -o " + out);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_EQ(lines_of(r.output), 1u) << r.output;
  EXPECT_NE(r.output.find("no topic /velodyne_points in the bag; it holds /imu (std_msgs/Header), /points "
                          "(sensor_msgs/PointCloud2), /tf (tf2_msgs/TFMessage) (--topic)"), std::string::npos) << r.output;
  r = run("build -q " + bag + " --topic /imu --tf-frame map -o " + out);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("topic /imu is std_msgs/Header, not sensor_msgs/PointCloud2 or sensor_msgs/LaserScan"),
            std::string::npos) << r.output;
  r = run("build -q " + bag + " --tf-frame map -o " + out);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("give --topic NAME"), std::string::npos) << r.output;
}

// Truncated and garbled bags: a one-line error and exit 1 (or a map, where the damage missed
// what is read), never a crash.
TEST(RosbagCli, CorruptBagsAreOneLineErrors) {
  testing::TempDir dir("rosbag_corrupt");
  const std::filesystem::path good = dir / "good.bag";
  std::vector<Eigen::Vector3f> points;
  for (int i = 0; i < 200; ++i) points.push_back({float(i % 7), float(i % 5) - 2, float(i % 3)});
  for (auto compression : {rosbag::compression::Uncompressed, rosbag::compression::BZ2}) {
    {
      rosbag::Bag bag(good.string(), rosbag::bagmode::Write);
      bag.setCompression(compression);
      bag.setChunkThreshold(4096);
      for (uint32_t t = 1; t <= 6; ++t) {
        write_tf(bag, "/tf", transform_msg("map", "lidar", ros::Time(t, 0), Rigid::Identity()));
        bag.write("/points", ros::Time(t, 0), cloud_msg("lidar", ros::Time(t, 0), points));
      }
    }
    const std::string bytes = testing::read_bytes(good);
    ASSERT_GT(bytes.size(), 10000u);
    const std::filesystem::path bad = dir / "bad.bag";
    const std::string build = "build -q " + bad.string() + " --topic /points --tf-frame map -o " + (dir / "m.bgk").string();
    for (size_t cut : {size_t(5), size_t(13), size_t(100), bytes.size() / 3, bytes.size() / 2, bytes.size() - 30}) {
      testing::write_bytes(bad, bytes.substr(0, cut));
      const Result r = run(build);
      EXPECT_EQ(r.status, 1) << cut << ": " << r.output;
      EXPECT_EQ(lines_of(r.output), 1u) << cut << ": " << r.output;
      EXPECT_EQ(r.output.rfind("bgkmap: error: " + bad.string() + ": ", 0), 0u) << r.output;
    }
    // A connection header (in the index, after the chunks) whose first field claims more bytes than
    // it holds: rosbag_storage read past its buffer (fuzz_rosbag, ASan).
    std::string bad_connection = bytes;
    const size_t definition = bad_connection.rfind("message_definition=");
    ASSERT_NE(definition, std::string::npos);
    const uint32_t huge = 0x7fff0000u;
    std::memcpy(&bad_connection[definition - 4], &huge, 4);
    testing::write_bytes(bad, bad_connection);
    const Result refused = run(build);
    EXPECT_EQ(refused.status, 1) << refused.output;
    EXPECT_EQ(lines_of(refused.output), 1u) << refused.output;
    EXPECT_NE(refused.output.find(": a connection record whose connection header is malformed"), std::string::npos)
        << refused.output;
    uint32_t seed = 12345;
    for (int trial = 0; trial < 24; ++trial) {
      std::string garbled = bytes;
      for (int k = 0; k < 4; ++k) {
        seed = seed * 1664525u + 1013904223u;
        garbled[seed % garbled.size()] = static_cast<char>(seed >> 24);
      }
      testing::write_bytes(bad, garbled);
      const Result r = run(build);
      EXPECT_TRUE(r.status == 0 || r.status == 1) << trial << ": status " << r.status << ": " << r.output;
      if (r.status == 1) {
        EXPECT_EQ(lines_of(r.output), 1u) << trial << ": " << r.output;
      }
    }
  }
}

// A bag is one input of --resume: its messages already in the map are passed over, the next bag's
// added, and the result is the map of both bags built at once, cell for cell.
TEST_F(Rosbags, ResumePassesOverTheBagsTheMapHolds) {
  const std::vector<Scan> scans = sim_scans("sim");
  write_cloud_bag(path("first.bag"), scans, 0, 2);
  write_cloud_bag(path("second.bag"), scans, 2, 1);
  const std::string inputs = " --topic /points --tf-frame map";
  Result r = run("build " + path("first.bag") + inputs + " -o " + path("first.bgk") + kBuildFlags);
  ASSERT_EQ(r.status, 0) << r.output;
  r = run("build " + path("first.bag") + " " + path("second.bag") + inputs + " --resume " + path("first.bgk") + " -o " +
          path("resumed.bgk") + kBuildFlags + " --report " + path("resumed.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(read_json(path("resumed.json"))["counts"]["scans_already_held"], 2);
  r = run("build " + path("first.bag") + " " + path("second.bag") + inputs + " -o " + path("both.bgk") + kBuildFlags);
  ASSERT_EQ(r.status, 0) << r.output;
  expect_same_cells(path("both.bgk"), path("resumed.bgk"), 0.0);
}

// A message too large for --max-memory is refused before it is read, naming the flag.
TEST(RosbagCli, LargeMessageMustFitMaxMemory) {
  testing::TempDir dir("rosbag_memory");
  const std::filesystem::path file = dir / "big.bag";
  {
    rosbag::Bag bag(file.string(), rosbag::bagmode::Write);
    write_tf(bag, "/tf", transform_msg("map", "lidar", ros::Time(1, 0), Rigid::Identity()));
    std::vector<Eigen::Vector3f> points(3'000'000, Eigen::Vector3f(1, 2, 3));  // 60 MB at 20 bytes a point
    bag.write("/points", ros::Time(1, 0), cloud_msg("lidar", ros::Time(1, 0), points));
  }
  const Result r = run("build -q " + file.string() + " --topic /points --tf-frame map --max-memory 100M -o " +
                       (dir / "m.bgk").string());
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_EQ(lines_of(r.output), 1u) << r.output;
  EXPECT_EQ(r.output.rfind("bgkmap: error: a chunk of " + file.string() + " (57.2 MiB of messages) needs", 0), 0u) << r.output;
  EXPECT_NE(r.output.find("--max-memory"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace bgkmap
