// Dynamic objects of the simulator: where each is at a scan, the scene at a scan against the same
// scene built by hand, scans cast into the scene at their time, the scene file round trip, and
// the truth at a time.
#include <gtest/gtest.h>

#include <octomap/OcTree.h>

#include "bgkmap/eval/truth.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/pcd_io.hpp"
#include "bgkmap/sim/presets.hpp"
#include "bgkmap/sim/raycaster.hpp"
#include "bgkmap/sim/simulate.hpp"
#include "bgkmap/sim/spec.hpp"
#include "support/test_support.hpp"

namespace bgkmap::sim {
namespace {

void expect_near(const Vec3d& a, const Vec3d& b) {
  EXPECT_NEAR(a.x, b.x, 1e-12);
  EXPECT_NEAR(a.y, b.y, 1e-12);
  EXPECT_NEAR(a.z, b.z, 1e-12);
}

TEST(DynamicObject, WalkerTurnsBackAtTheEndOfAnOpenPathAndLoopsAClosedOne) {
  DynamicObject w{"w", Sphere({0, 0, 0}, 0.2), 2};
  w.path = {{0, 0, 0}, {2, 0, 0}};
  w.speed_m_per_scan = 0.5;
  w.validate();
  expect_near(w.offset_at(0), {0, 0, 0});  // before it appears: at path[0]
  expect_near(w.offset_at(2), {0, 0, 0});
  expect_near(w.offset_at(4), {1, 0, 0});
  expect_near(w.offset_at(6), {2, 0, 0});
  expect_near(w.offset_at(7), {1.5, 0, 0});  // on its way back
  expect_near(w.offset_at(10), {0, 0, 0});
  expect_near(w.offset_at(11), {0.5, 0, 0});
  DynamicObject loop{"l", Sphere({1, 1, 0}, 0.2), 0};
  loop.path = {{1, 1, 0}, {3, 1, 0}, {3, 3, 0}};
  loop.closed = true;
  loop.speed_m_per_scan = 1;
  expect_near(loop.offset_at(3), {2, 1, 0});  // (3, 2) on the second leg
  const double diagonal = std::sqrt(8.0);
  EXPECT_NEAR(loop.offset_at(5).x, 2 - (1 / diagonal) * 2, 1e-12);  // 1 m back along (3,3) -> (1,1)
  const auto sphere = std::get<Sphere>(loop.shape_at(3));
  expect_near(sphere.center(), {3, 2, 0});
}

TEST(DynamicObject, PresenceAndBadObjectsAreRefused) {
  DynamicObject door{"door", Box({0, 0, 0}, {1, 1, 1}), 1, 4};
  EXPECT_FALSE(door.present_at(0));
  EXPECT_TRUE(door.present_at(1));
  EXPECT_TRUE(door.present_at(3));
  EXPECT_FALSE(door.present_at(4));
  DynamicObject bad = door;
  bad.disappear = 1;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
  bad = door;
  bad.shape = HalfSpace({0, 0, 0}, {0, 0, 1});
  EXPECT_THROW(bad.validate(), std::invalid_argument);
  bad = door;
  bad.speed_m_per_scan = 1;  // no path
  EXPECT_THROW(bad.validate(), std::invalid_argument);
}

// A wall at x = 4 and a door at x = 2 that is gone from scan 3.
SimulationSpec door_spec() {
  SimulationSpec spec;
  spec.scene.primitives.push_back(Box({4, 0, 1}, {0.2, 4, 2}));
  spec.scene.bounds = Box3d{{-1, -2, 0}, {5, 2, 2}};
  spec.scene.dynamic.push_back({"door", Box({2, 0, 1}, {0.2, 2, 2}), 0, 3});
  spec.sensor = sensor_preset("planar");
  spec.sensor.range_noise_sigma_m = 0;
  spec.trajectory.waypoints = {{{0, 0, 1}, 0.0}};
  spec.trajectory.scans = 5;
  spec.truth_resolution_m = 0.1;
  spec.validate();
  return spec;
}

TEST(DynamicScene, SceneAtAScanIsTheHandBuiltScene) {
  const SimulationSpec spec = door_spec();
  Scene closed{spec.scene.primitives, spec.scene.bounds, {}};
  closed.primitives.push_back(Box({2, 0, 1}, {0.2, 2, 2}));
  const Scene open{spec.scene.primitives, spec.scene.bounds, {}};
  const Ray ray{{0, 0, 1}, {1, 0, 0}};
  for (int scan = 0; scan < 5; ++scan) {
    const Scene now = scene_at(spec.scene, scan);
    EXPECT_TRUE(now.dynamic.empty());
    const auto got = cast_brute_force(now, ray, 10);
    const auto want = cast_brute_force(scan < 3 ? closed : open, ray, 10);
    ASSERT_TRUE(got && want);
    EXPECT_DOUBLE_EQ(got->t, want->t) << "scan " << scan;
  }
  EXPECT_DOUBLE_EQ(cast_brute_force(scene_at(spec.scene, 0), ray, 10)->t, 1.9);
  EXPECT_DOUBLE_EQ(cast_brute_force(scene_at(spec.scene, 3), ray, 10)->t, 3.9);
}

TEST(DynamicScene, ScansAreCastIntoTheSceneAtTheirTimeAndTruthIsTheLastScans) {
  const testing::TempDir dir("sim-dynamic");
  const SimulationSpec spec = door_spec();
  SimulateOptions options;
  options.output_dir = dir.path();
  simulate(spec, options);
  const std::vector<Vec3d> directions = beam_directions(spec.sensor);
  const std::vector<Pose> poses = sample_poses(spec.trajectory);
  for (int scan = 0; scan < 5; ++scan) {
    const Scene now = scene_at(spec.scene, scan);
    ScanCounts counts;
    const Scan want = simulate_scan(Raycaster(now), spec.sensor, directions, poses[scan], spec.seed, scan, counts);
    const Scan got = read_pcd(dir.path() / "scans" / scan_file_name(scan, 5));
    ASSERT_EQ(got.points.size(), want.points.size());
    for (size_t i = 0; i < got.points.size(); ++i) {
      if (std::isnan(want.points[i].x)) continue;
      ASSERT_EQ(got.points[i].x, want.points[i].x) << "scan " << scan << " beam " << i;
      ASSERT_EQ(got.points[i].y, want.points[i].y);
    }
  }
  // truth.bt: the door's cells free (it is gone at the last scan), the wall's occupied.
  octomap::OcTree tree((dir.path() / "truth.bt").string());
  const auto* door = tree.search(2.05, 0.05, 1.05);
  const auto* wall = tree.search(4.05, 0.05, 1.05);
  ASSERT_TRUE(door && wall);
  EXPECT_FALSE(tree.isNodeOccupied(door));
  EXPECT_TRUE(tree.isNodeOccupied(wall));

  // The scene file's truth at a scan.
  GridParams gp;
  gp.resolution_m = 0.1;
  const Grid grid(gp);
  const CellIndex door_cell = grid.cell_of(2.05, 0.05, 1.05);
  const auto at = [&](std::optional<int> scan) {
    return eval::load_truth(dir.path() / "scene.yaml", grid, scan)->label(door_cell);
  };
  EXPECT_EQ(at(0), eval::TruthLabel::kOccupied);
  EXPECT_EQ(at(2), eval::TruthLabel::kOccupied);
  EXPECT_EQ(at(3), eval::TruthLabel::kFree);
  EXPECT_EQ(at(std::nullopt), eval::TruthLabel::kFree);  // the last scan
  EXPECT_THROW(at(5), InputError);
  EXPECT_THROW(eval::load_truth(dir.path() / "truth.bt", grid, 1), InputError);
}

TEST(DynamicScene, SceneFileRoundTripsAndBadObjectsNameTheLine) {
  const SimulationSpec preset = make_preset("dynamic");
  const SimulationSpec back = parse_spec(spec_to_yaml(preset), "dynamic.yaml");
  EXPECT_EQ(spec_to_yaml(back), spec_to_yaml(preset));
  ASSERT_EQ(back.scene.dynamic.size(), 4u);
  EXPECT_EQ(back.scene.dynamic[0].name, "door");
  EXPECT_EQ(back.scene.dynamic[0].disappear, 20);
  EXPECT_DOUBLE_EQ(back.scene.dynamic[2].speed_m_per_scan, 0.2);

  const std::string base =
      "bounds: {min: [-1, -1, -1], max: [5, 5, 3]}\ntrajectory: {station: [0, 0, 1], scans: 3}\n"
      "primitives:\n  - {type: box, center: [4, 0, 1], size: [0.2, 4, 2]}\n";
  EXPECT_NO_THROW(parse_spec(base + "dynamic:\n  - {shape: {type: sphere, center: [2, 0, 1], radius: 0.3}, disappear: 2}\n", "ok.yaml"));
  try {
    parse_spec(base + "dynamic:\n  - {name: d, shape: {type: plane, point: [0, 0, 0], normal: [0, 0, 1]}}\n", "bad.yaml");
    FAIL() << "a moving plane was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.yaml"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("line 6"), std::string::npos) << e.what();
  }
  const std::string unbounded = "trajectory: {station: [0, 0, 1], scans: 3}\nprimitives:\n"
                                "  - {type: box, center: [4, 0, 1], size: [0.2, 4, 2]}\n"
                                "dynamic:\n  - {shape: {type: sphere, center: [2, 0, 1], radius: 0.3}}\n";
  EXPECT_THROW(parse_spec(unbounded, "unbounded.yaml"), InputError);
}

}  // namespace
}  // namespace bgkmap::sim
