// The one pose rule of every input format, through `bgkmap build` as a user runs it (docs/USAGE.md,
// "Poses"): three simulated scans (world-frame PCDs with VIEWPOINT, and poses.txt) written again as
// PCDs without a pose, as PLY in the world and in the sensor frame, and as a KITTI sequence. Each
// build either maps the same cells as the PCD folder's, bit for bit, or is refused in one line
// naming the file and the flag that fixes it.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "bgkmap/io/native_map.hpp"
#include "bgkmap/io/pcd_io.hpp"
#include "bgkmap/io/pose_list.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

namespace fs = std::filesystem;
using testing::CommandResult;

CommandResult run(const std::string& args) { return testing::run_command(std::string(BGKMAP_CLI) + " " + args); }

// A small map of the planar scans: 0.2 m cells, the simulator's 8 m range.
const char* const kBuildFlags = " -q --backend cpu --threads 1 --max-range 8 --resolution 0.2";

std::string number(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.17g", v);
  return text;
}

// A TUM line of poses.txt for a pose (float fields written so they read back as the same floats).
std::string tum_line(const Pose& p) {
  char line[256];
  std::snprintf(line, sizeof line, "0 %.9g %.9g %.9g %.9g %.9g %.9g %.9g\n", p.position.x, p.position.y, p.position.z,
                p.qx, p.qy, p.qz, p.qw);
  return line;
}

void write_ply(const fs::path& file, const std::vector<Vec3f>& points) {
  std::string text = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(points.size()) +
                     "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
  char line[128];
  for (const Vec3f& p : points) {
    std::snprintf(line, sizeof line, "%.9g %.9g %.9g\n", p.x, p.y, p.z);
    text += line;
  }
  testing::write_bytes(file, text);
}

// A scan's pose as a rigid transform, in double.
Eigen::Matrix4d matrix_of(const Pose& p) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.block<3, 3>(0, 0) = Eigen::Quaterniond(p.qw, p.qx, p.qy, p.qz).normalized().toRotationMatrix();
  m.block<3, 1>(0, 3) = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
  return m;
}

// m * p rounded to float, summed in the order the KITTI reader sums (so the two agree bit for bit).
Vec3f transformed(const Eigen::Matrix4d& m, const Vec3f& p) {
  const double x = p.x, y = p.y, z = p.z;
  return {static_cast<float>(m(0, 0) * x + m(0, 1) * y + m(0, 2) * z + m(0, 3)),
          static_cast<float>(m(1, 0) * x + m(1, 1) * y + m(1, 2) * z + m(1, 3)),
          static_cast<float>(m(2, 0) * x + m(2, 1) * y + m(2, 2) * z + m(2, 3))};
}

std::string matrix_text(const Eigen::Matrix4d& m) {
  std::string s;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) s += (s.empty() ? "" : " ") + number(m(r, c));
  return s;
}

class ScanPoses : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::make_temp_dir("poses");
    const CommandResult sim = run("simulate structured -q --sensor planar --scans 3 --truth-resolution 0 -o " + path("sim"));
    ASSERT_EQ(sim.status, 0) << sim.output;
    const ScanSource simulated({dir_ / "sim" / "scans"});
    for (const fs::path& file : simulated.files()) scans_.push_back(read_pcd(file));
    for (const PoseRecord& r : read_pose_list(dir_ / "sim" / "poses.txt")) poses_.push_back(r.pose);
    ASSERT_EQ(scans_.size(), 3u);
    ASSERT_EQ(poses_.size(), 3u);
    ASSERT_TRUE(rotates(poses_[1]));  // the trajectory turns: the points' frame matters
    for (size_t i = 0; i < 3; ++i) ASSERT_EQ(scans_[i].pose.position.x, poses_[i].position.x);
    const CommandResult reference = build(path("sim/scans"), "sim.bgk");
    ASSERT_EQ(reference.status, 0) << reference.output;
    ASSERT_GT(map("sim.bgk").block_count(), 0u);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  CommandResult build(const std::string& inputs_and_flags, const std::string& map_name) const {
    return run("build " + inputs_and_flags + " -o " + path(map_name) + " --report " + path(map_name + ".json") + kBuildFlags);
  }
  BgkMap map(const std::string& name) const { return read_native_map(dir_ / name); }
  nlohmann::json pose_sources(const std::string& map_name) const {
    std::ifstream in(dir_ / (map_name + ".json"));
    return nlohmann::json::parse(in)["counts"]["pose_sources"];
  }
  // Each scan's points through `points_of`, as a folder of PCD files posed by `pose_of` (nullopt:
  // written without a pose, PCL's default VIEWPOINT).
  template <typename Points, typename PoseOf>
  void write_pcds(const std::string& folder, Points points_of, PoseOf pose_of) const {
    fs::create_directories(dir_ / folder);
    for (size_t i = 0; i < scans_.size(); ++i) {
      Scan scan;
      scan.points = points_of(i);
      const std::optional<Pose> pose = pose_of(i);
      scan.has_own_pose = pose.has_value();
      if (pose) scan.pose = *pose;
      write_pcd(dir_ / folder / ("s_" + std::to_string(i) + ".pcd"), scan);
    }
  }
  // A refused build: non-zero exit, one line naming `file` and each of `flags`, no map written.
  void expect_refused(const CommandResult& r, const std::string& file, const std::vector<std::string>& flags,
                      const std::string& map_name) const {
    EXPECT_NE(r.status, 0) << r.output;
    EXPECT_EQ(r.output.find('\n'), r.output.size() - 1) << r.output;
    EXPECT_NE(r.output.find(file + ": "), std::string::npos) << r.output;
    for (const std::string& flag : flags) EXPECT_NE(r.output.find(flag), std::string::npos) << flag << ": " << r.output;
    EXPECT_FALSE(fs::exists(dir_ / map_name)) << r.output;
  }

  fs::path dir_;
  std::vector<Scan> scans_;  // the simulated scans: world-frame points, pose = VIEWPOINT
  std::vector<Pose> poses_;  // poses.txt
};

// PCL writes VIEWPOINT 0 0 0 1 0 0 0 for a cloud without a pose, and a PCD may have no VIEWPOINT:
// either was mapped with the sensor at the origin. Now they are refused, naming the flags.
TEST_F(ScanPoses, PcdWithoutAViewpointOrWithPclsDefaultIsRefusedNamingTheFlags) {
  write_pcds("default", [&](size_t i) { return scans_[i].points; }, [](size_t) { return std::optional<Pose>(); });
  CommandResult r = build(path("default"), "default.bgk");
  expect_refused(r, path("default/s_0.pcd"), {"0 0 0 1 0 0 0", "--origin X,Y,Z or --poses FILE"}, "default.bgk");

  fs::create_directories(dir_ / "none");
  testing::write_bytes(dir_ / "none" / "s.pcd", "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
                                                "WIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n3 1 1\n");
  r = build(path("none"), "none.bgk");
  expect_refused(r, path("none/s.pcd"), {"--origin X,Y,Z or --poses FILE"}, "none.bgk");
}

// --poses and --origin give PCDs without a pose of their own theirs: the same map as the
// simulator's PCDs with VIEWPOINT (before, --origin was ignored and --poses refused for PCDs).
TEST_F(ScanPoses, PosesAndOriginApplyToPcdsWithoutAPose) {
  write_pcds("default", [&](size_t i) { return scans_[i].points; }, [](size_t) { return std::optional<Pose>(); });
  // The poses turn, and these points could be in either frame: refused until --frame says.
  CommandResult r = build(path("default") + " --poses " + path("sim/poses.txt"), "unsaid.bgk");
  expect_refused(r, path("sim/poses.txt"), {"line 4: a rotated pose for " + path("default/s_1.pcd"), "--frame world or --frame sensor"},
                 "unsaid.bgk");
  r = build(path("default") + " --poses " + path("sim/poses.txt") + " --frame world", "posed.bgk");
  ASSERT_EQ(r.status, 0) << r.output;
  testing::expect_same_cells(map("sim.bgk"), map("posed.bgk"));
  EXPECT_EQ(pose_sources("posed.bgk"), nlohmann::json({{"--poses", 3}}));
  EXPECT_EQ(pose_sources("sim.bgk"), nlohmann::json({{"PCD VIEWPOINT", 3}}));

  // --origin 1,1,0.1: the map of the same PCDs with that VIEWPOINT.
  Pose at;
  at.position = {1.0f, 1.0f, 0.1f};
  write_pcds("at", [&](size_t i) { return scans_[i].points; }, [&](size_t) { return std::optional<Pose>(at); });
  ASSERT_EQ(build(path("at"), "at.bgk").status, 0);
  r = build(path("default") + " --origin 1,1,0.1", "origin.bgk");
  ASSERT_EQ(r.status, 0) << r.output;
  testing::expect_same_cells(map("at.bgk"), map("origin.bgk"));
  EXPECT_EQ(pose_sources("origin.bgk"), nlohmann::json({{"--origin", 3}}));
  // --origin 0,0,0 says the sensor was at the origin: taken (the refusal is of a pose not given).
  EXPECT_EQ(build(path("default") + " --origin 0,0,0", "zero.bgk").status, 0);
}

// A file with a pose of its own beside --poses or --origin: which one was meant is not guessed.
TEST_F(ScanPoses, PosesOrOriginBesideAFilesOwnPoseIsRefused) {
  CommandResult r = build(path("sim/scans") + " --origin 1,1,0.1", "both.bgk");
  expect_refused(r, path("sim/scans/scan_00000.pcd"), {"VIEWPOINT", "--origin"}, "both.bgk");
  r = build(path("sim/scans") + " --poses " + path("sim/poses.txt") + " --frame world", "both.bgk");
  expect_refused(r, path("sim/scans/scan_00000.pcd"), {"VIEWPOINT", "--poses"}, "both.bgk");
  testing::write_bytes(dir_ / "scan.dat", "NODE 0.5 0 1 0 0 0\n1 0 1\n");
  r = build(path("scan.dat") + " --origin 1,1,0.1", "both.bgk");
  expect_refused(r, path("scan.dat"), {"NODE", "--origin"}, "both.bgk");
}

// PLY (no pose of its own) with --poses: world-frame points give the PCD folder's map; sensor-frame
// points, with the poses' rotations applied under --frame sensor (or its alias --apply-viewpoint,
// or the config's frame), the map of their world points. Before, the rotations were dropped
// without --apply-viewpoint, rc 0.
TEST_F(ScanPoses, PlyWithPosesInTheWorldAndInTheSensorFrameMapAsThePcdFolder) {
  fs::create_directories(dir_ / "world_ply");
  for (size_t i = 0; i < scans_.size(); ++i) write_ply(dir_ / "world_ply" / ("s_" + std::to_string(i) + ".ply"), scans_[i].points);
  CommandResult r = build(path("world_ply") + " --poses " + path("sim/poses.txt") + " --frame world", "world_ply.bgk");
  ASSERT_EQ(r.status, 0) << r.output;
  testing::expect_same_cells(map("sim.bgk"), map("world_ply.bgk"));

  // Sensor-frame PLYs: R^T (p - t). The reference is the PCD folder of the world points these poses
  // give (Pose::transform, as preprocessing applies a pose), with the same origins.
  fs::create_directories(dir_ / "sensor_ply");
  std::vector<std::vector<Vec3f>> local(scans_.size());
  for (size_t i = 0; i < scans_.size(); ++i) {
    const Eigen::Matrix4d to_sensor = matrix_of(poses_[i]).inverse();
    for (const Vec3f& p : scans_[i].points) local[i].push_back(transformed(to_sensor, p));
    write_ply(dir_ / "sensor_ply" / ("s_" + std::to_string(i) + ".ply"), local[i]);
  }
  write_pcds(
      "sensor_reference",
      [&](size_t i) {
        std::vector<Vec3f> world;
        for (const Vec3f& p : local[i]) world.push_back(poses_[i].transform(p));
        return world;
      },
      [&](size_t i) { return std::optional<Pose>(poses_[i]); });
  ASSERT_EQ(build(path("sensor_reference"), "sensor_reference.bgk").status, 0);
  const std::string posed = path("sensor_ply") + " --poses " + path("sim/poses.txt");
  r = build(posed, "unsaid.bgk");
  expect_refused(r, path("sim/poses.txt"), {"a rotated pose for " + path("sensor_ply/s_1.ply"), "--frame"}, "unsaid.bgk");
  testing::write_bytes(dir_ / "frame.yaml", "frame: sensor\n");
  for (const std::string& frame : std::vector<std::string>{" --frame sensor", " --apply-viewpoint", " --config " + path("frame.yaml")}) {
    r = build(posed + frame, "sensor_ply.bgk");
    ASSERT_EQ(r.status, 0) << frame << ": " << r.output;
    testing::expect_same_cells(map("sensor_reference.bgk"), map("sensor_ply.bgk"));
    EXPECT_TRUE(map("sensor_ply.bgk").params().preprocess.apply_viewpoint) << frame;
    fs::remove(dir_ / "sensor_ply.bgk");
  }
  // The sensor-frame points taken as world-frame are another map: the rule is not vacuous.
  r = build(posed + " --frame world", "wrong.bgk");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(map("wrong.bgk").cells_with_evidence(), map("sensor_reference.bgk").cells_with_evidence());
}

// A KITTI sequence of the same scans: velodyne/*.bin in each scan's sensor frame, poses.txt the
// camera poses P_i = Tr G_i Tr^-1 of the scans' poses G_i relative to the first, and a Tr that
// swaps and negates axes (velodyne x forward, camera z forward) so every product is exact. By
// default the map is in the velodyne frame of the first scan, cell for cell the map of the PCD
// folder of G_i p (tolerance: none, bit for bit); --kitti-frame camera gives the map of Tr G_i p,
// and records the frame in the .bgk header and the report.
TEST_F(ScanPoses, KittiSequenceMapsInTheVelodyneFrameOfTheFirstScanOrTheCameraFrame) {
  Eigen::Matrix4d tr = Eigen::Matrix4d::Identity();
  tr.block<3, 3>(0, 0) << 0, -1, 0, 0, 0, -1, 1, 0, 0;  // camera x = -velodyne y, y = -z, z = x
  const Eigen::Matrix4d first_inverse = matrix_of(poses_[0]).inverse();
  const fs::path seq = dir_ / "kitti" / "00";
  fs::create_directories(seq / "velodyne");
  testing::write_bytes(seq / "calib.txt", "P0: 1 0 0 0 0 1 0 0 0 0 1 0\nTr: " + matrix_text(tr) + "\n");
  std::string kitti_poses, velodyne_poses, camera_poses;
  std::vector<std::vector<Vec3f>> local(scans_.size());
  std::vector<Eigen::Matrix4d> relative(scans_.size());
  for (size_t i = 0; i < scans_.size(); ++i) {
    const Eigen::Matrix4d to_sensor = matrix_of(poses_[i]).inverse();
    std::string bytes;
    for (const Vec3f& p : scans_[i].points) {
      local[i].push_back(transformed(to_sensor, p));
      const float v[4] = {local[i].back().x, local[i].back().y, local[i].back().z, 0.0f};
      bytes.append(reinterpret_cast<const char*>(v), sizeof v);
    }
    char name[32];
    std::snprintf(name, sizeof name, "%06zu.bin", i);
    testing::write_bytes(seq / "velodyne" / name, bytes);
    relative[i] = i == 0 ? Eigen::Matrix4d(Eigen::Matrix4d::Identity()) : Eigen::Matrix4d(first_inverse * matrix_of(poses_[i]));
    kitti_poses += matrix_text(tr * relative[i] * tr.transpose()) + "\n";
  }
  testing::write_bytes(seq / "poses.txt", kitti_poses);
  // World-frame PCDs without a pose, their origins by --poses (identity orientation: world-frame
  // points need none).
  for (const bool camera : {false, true}) {
    const std::string folder = camera ? "camera_reference" : "velodyne_reference";
    std::string lines;
    write_pcds(
        folder,
        [&](size_t i) {
          const Eigen::Matrix4d m = camera ? Eigen::Matrix4d(tr * relative[i]) : relative[i];
          Pose origin;
          origin.position = transformed(m, {0, 0, 0});
          lines += tum_line(origin);
          std::vector<Vec3f> world;
          for (const Vec3f& p : local[i]) world.push_back(transformed(m, p));
          return world;
        },
        [](size_t) { return std::optional<Pose>(); });
    testing::write_bytes(dir_ / (folder + ".txt"), lines);
    ASSERT_EQ(build(path(folder) + " --poses " + path(folder + ".txt"), folder + ".bgk").status, 0) << folder;
  }
  CommandResult r = build(seq.string(), "kitti.bgk");
  ASSERT_EQ(r.status, 0) << r.output;
  testing::expect_same_cells(map("velodyne_reference.bgk"), map("kitti.bgk"));
  EXPECT_EQ(map("kitti.bgk").params().preprocess.kitti_frame, KittiFrame::kVelodyne);
  EXPECT_EQ(pose_sources("kitti.bgk"), nlohmann::json({{"KITTI poses.txt", 3}}));

  r = build(seq.string() + " --kitti-frame camera", "kitti_camera.bgk");
  ASSERT_EQ(r.status, 0) << r.output;
  testing::expect_same_cells(map("camera_reference.bgk"), map("kitti_camera.bgk"));
  EXPECT_EQ(map("kitti_camera.bgk").params().preprocess.kitti_frame, KittiFrame::kCamera);
  std::ifstream in(dir_ / "kitti_camera.bgk.json");
  EXPECT_EQ(nlohmann::json::parse(in)["params"]["kitti_frame"], "camera");
  // Resuming the camera-frame map in the velodyne frame would mix two worlds: refused.
  r = run("build " + seq.string() + " --resume " + path("kitti_camera.bgk") + " -o " + path("mixed.bgk") + kBuildFlags);
  EXPECT_NE(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("kitti_frame"), std::string::npos) << r.output;
  // The sequence has poses of its own.
  r = build(seq.string() + " --origin 1,1,0.1", "both.bgk");
  expect_refused(r, seq.string(), {"KITTI poses.txt", "--origin"}, "both.bgk");
}

}  // namespace
}  // namespace bgkmap
