// Scene files: everything survives a write/read round trip; bad files give one-line errors that
// name the file, the line and the problem.
#include <gtest/gtest.h>

#include <fstream>
#include <random>

#include "bgkmap/io/errors.hpp"
#include "bgkmap/sim/presets.hpp"
#include "bgkmap/sim/spec.hpp"
#include "sim/sim_test_util.hpp"
#include "support/test_support.hpp"

namespace bgkmap::sim {
namespace {

SimulationSpec every_feature_spec() {
  std::mt19937 rng(21);
  SimulationSpec spec;
  spec.name = "round-trip";
  spec.seed = 123456789012345ull;
  spec.truth_resolution_m = 0.05;
  spec.scene.bounds = Box3d{{-10, -10.25, -3}, {10, 10, 1.0 / 3}};
  spec.scene.primitives = testing_support::random_primitives(rng, 3);
  spec.sensor = sensor_preset("vlp16");
  spec.sensor.name = "my-lidar";
  spec.sensor.rings = 32;
  spec.sensor.elevation_min_deg = -25.1;
  spec.sensor.max_range_m = 0.1 + 0.2;  // not a short decimal
  spec.sensor.dropout = 0.125;
  spec.trajectory.waypoints = {{{0, 0, 1}, 0.0}, {{1e-7, 3, 1}, 90.0}, {{-2, 3, 1.5}, 181.5}};
  spec.trajectory.closed = true;
  spec.trajectory.scans = 17;
  return spec;
}

TEST(SceneYaml, RoundTripKeepsEveryValue) {
  const SimulationSpec spec = every_feature_spec();
  const std::string text = spec_to_yaml(spec);
  const SimulationSpec back = parse_spec(text, "mem.yaml");
  EXPECT_EQ(spec_to_yaml(back), text);
  EXPECT_EQ(back.name, spec.name);
  EXPECT_EQ(back.seed, spec.seed);
  EXPECT_EQ(back.truth_resolution_m, spec.truth_resolution_m);
  EXPECT_EQ(back.scene.bounds->max.z, 1.0 / 3);
  EXPECT_EQ(back.sensor.max_range_m, 0.1 + 0.2);
  EXPECT_EQ(back.sensor.elevation_min_deg, -25.1);
  EXPECT_EQ(back.sensor.rings, 32);
  EXPECT_EQ(back.trajectory.waypoints[1].position.x, 1e-7);
  EXPECT_EQ(*back.trajectory.waypoints[2].yaw_deg, 181.5);
  EXPECT_TRUE(back.trajectory.closed);
  ASSERT_EQ(back.scene.primitives.size(), spec.scene.primitives.size());
  // Same solids: same type, and the same answer to inside tests everywhere.
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-5, 5);
  for (size_t i = 0; i < spec.scene.primitives.size(); ++i) {
    ASSERT_EQ(back.scene.primitives[i].index(), spec.scene.primitives[i].index());
    for (int k = 0; k < 2000; ++k) {
      const Vec3d p{u(rng), u(rng), u(rng)};
      ASSERT_EQ(contains(back.scene.primitives[i], p), contains(spec.scene.primitives[i], p));
    }
  }
}

TEST(SceneYaml, PresetsRoundTripAndAreDeterministic) {
  for (const std::string& name : preset_names()) {
    const std::string text = spec_to_yaml(make_preset(name));
    EXPECT_EQ(spec_to_yaml(parse_spec(text, name + ".yaml")), text) << name;
    EXPECT_EQ(spec_to_yaml(make_preset(name)), text) << name;
  }
  EXPECT_THROW(make_preset("office"), std::invalid_argument);
}

TEST(SceneYaml, HandWrittenFileWithShortcuts) {
  const char* text = R"(
sensor: {preset: planar, max_range: 12}
trajectory:
  scans: 3
  waypoints: [[0, 0, 0.3], [2, 0, 0.3]]
primitives:
  - {type: box, center: [3, 0, 0], size: [0.2, 4, 1]}
  - {type: heightfield, origin: [-1, -1], cell: 1, base_z: -2, heights: [[0, 0], [0, 1]]}
)";
  const SimulationSpec spec = parse_spec(text, "/some/where/hand.yaml");
  EXPECT_EQ(spec.name, "hand");
  EXPECT_EQ(spec.sensor.name, "planar");
  EXPECT_EQ(spec.sensor.rings, 1);
  EXPECT_EQ(spec.sensor.max_range_m, 12);
  EXPECT_EQ(spec.trajectory.waypoints.size(), 2u);
  EXPECT_FALSE(spec.scene.bounds);
  EXPECT_EQ(spec.seed, 1u);
}

void expect_error(const std::string& text, const std::string& fragment) {
  try {
    parse_spec(text, "bad.yaml");
    ADD_FAILURE() << "no error for:\n" << text;
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind("bad.yaml: ", 0), 0u) << what;
    EXPECT_NE(what.find(fragment), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
}

TEST(SceneYaml, BadFilesGiveOneLineErrors) {
  const std::string tail = "trajectory: {station: {position: [0, 0, 1]}}\n";
  const std::string box = "primitives: [{type: box, center: [0, 0, 0], size: [1, 1, 1]}]\n";
  expect_error("primitives: [\n", "not valid YAML");
  expect_error(tail + "primitives: [{type: cone, center: [0, 0, 0]}]\n", "unknown primitive type 'cone'");
  expect_error(tail + "primitives:\n  - {type: box, centre: [0, 0, 0], size: [1, 1, 1]}\n", "line 3: unknown key 'centre'");
  expect_error(tail + "primitives: [{type: sphere, center: [0, 0], radius: 1}]\n", "list of 3 numbers");
  expect_error(tail + "primitives: [{type: sphere, center: [0, 0, 0], radius: -1}]\n", "radius must be positive");
  expect_error(tail + "primitives: [{type: sphere, center: [0, 0, x], radius: 1}]\n", "cannot read 'x'");
  expect_error(box, "needs 'trajectory'");
  expect_error(tail + "primitives: [{type: plane, point: [0, 0, 0], normal: [0, 0, 1]}]\n", "no bounds");
  expect_error(tail + box + "sensor: lidar\n", "unknown sensor 'lidar'");
  expect_error(tail + box + "sensor: {preset: vlp16, rings: 0}\n", "rings");
  expect_error(tail + box + "truth_resolution: 0.00001\n", "does not fit");
  expect_error("trajectory: {scans: 2, waypoints: [{position: [0, 0, 0], yaw_deg: 3}, {position: [1, 0, 0]}]}\n" + box,
               "yaw_deg on every waypoint or on none");
}

TEST(SceneYaml, FilesAndSensorFiles) {
  const auto dir = testing::make_temp_dir("sim-yaml");
  const SimulationSpec spec = make_preset("unstructured");
  save_spec(dir / "scene.yaml", spec);
  EXPECT_EQ(spec_to_yaml(load_spec(dir / "scene.yaml")), spec_to_yaml(spec));
  EXPECT_THROW(load_spec(dir / "missing.yaml"), InputError);

  std::ofstream(dir / "sensor.yaml") << "kind: pinhole\nwidth: 4\nheight: 3\nhorizontal_fov_deg: 60\nmax_range: 5\n";
  const SensorModel camera = load_sensor(dir / "sensor.yaml");
  EXPECT_EQ(camera.kind, SensorKind::kPinhole);
  EXPECT_EQ(camera.beam_count(), 12u);
  EXPECT_EQ(camera.name, "custom");
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap::sim
