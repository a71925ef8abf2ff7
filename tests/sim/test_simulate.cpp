// The simulate driver end to end: the structured preset's files are what `build` reads (PCD with
// VIEWPOINT = pose), the points lie on the scene's surfaces, no-returns and dropouts reach the
// mapper's preprocessing as documented.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>

#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/io/pcd_io.hpp"
#include "bgkmap/sim/presets.hpp"
#include "bgkmap/sim/simulate.hpp"
#include "support/test_support.hpp"

namespace bgkmap::sim {
namespace {

std::vector<std::vector<double>> read_pose_lines(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::vector<std::vector<double>> rows;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    std::vector<double> row(8);
    for (double& v : row) fields >> v;
    rows.push_back(row);
  }
  return rows;
}

TEST(Simulate, StructuredPresetIsReadableWithPoses) {
  const auto dir = testing::make_temp_dir("sim-structured");
  const SimulationSpec spec = make_preset("structured");
  SimulateOptions options;
  options.output_dir = dir;
  size_t progress_calls = 0;
  options.on_scan = [&](size_t done, size_t total) {
    ++progress_calls;
    EXPECT_EQ(total, 12u);
    EXPECT_EQ(done, progress_calls);
  };
  const SimulateReport report = simulate(spec, options);
  EXPECT_EQ(report.scans, 12u);
  EXPECT_EQ(progress_calls, 12u);
  EXPECT_EQ(report.counts.beams, 12u * 28800u);
  EXPECT_EQ(report.counts.returns, report.counts.beams);  // rooms under a ceiling: every beam returns
  ASSERT_TRUE(report.truth);

  const std::vector<Pose> poses = sample_poses(spec.trajectory);
  const auto pose_lines = read_pose_lines(dir / "poses.txt");
  ASSERT_EQ(pose_lines.size(), 12u);
  uint64_t bytes = 0;
  for (size_t i = 0; i < 12; ++i) {
    const auto file = dir / "scans" / scan_file_name(i, 12);
    bytes += std::filesystem::file_size(file);
    const Scan scan = read_pcd(file);
    ASSERT_EQ(scan.points.size(), 28800u);
    EXPECT_EQ(scan.pose.position.x, poses[i].position.x);
    EXPECT_EQ(scan.pose.position.y, poses[i].position.y);
    EXPECT_EQ(scan.pose.position.z, poses[i].position.z);
    EXPECT_NEAR(scan.pose.qw, poses[i].qw, 1e-7);
    EXPECT_NEAR(scan.pose.qz, poses[i].qz, 1e-7);
    EXPECT_NEAR(pose_lines[i][0], 0.1 * i, 1e-9);
    EXPECT_NEAR(pose_lines[i][1], poses[i].position.x, 1e-6);
    EXPECT_NEAR(pose_lines[i][2], poses[i].position.y, 1e-6);
    EXPECT_NEAR(pose_lines[i][6], poses[i].qz, 1e-7);
    EXPECT_NEAR(pose_lines[i][7], poses[i].qw, 1e-7);
    // Returns lie within the scene's walls, in range.
    for (const Vec3f& p : scan.points) {
      ASSERT_TRUE(std::isfinite(p.x));
      ASSERT_GE(p.x, -0.05f);
      ASSERT_LE(p.x, 10.05f);
      ASSERT_LE(p.z, 2.05f);
    }
  }
  EXPECT_EQ(bytes, report.scan_bytes);
  EXPECT_EQ(spec_to_yaml(load_spec(dir / "scene.yaml")), spec_to_yaml(spec));
  EXPECT_TRUE(std::filesystem::is_regular_file(dir / "truth.bt"));
  // The rooms' region is 10.8 x 7.6 x 2.8 m: a 13.5 m diagonal, shorter than the VLP-16's 100 m.
  EXPECT_EQ(recommended_build_flags(spec), "--max-range 14");
  EXPECT_EQ(recommended_max_range(make_preset("campus")), 100.0);

  // A second run into the same folder must not mix scans: refused, or replaced with --overwrite.
  SimulationSpec fewer = spec;
  fewer.trajectory.scans = 2;
  fewer.truth_resolution_m = 0;
  EXPECT_THROW(simulate(fewer, {dir, false, {}, {}}), std::runtime_error);
  simulate(fewer, {dir, true, {}, {}});
  size_t pcds = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir / "scans")) pcds += e.path().extension() == ".pcd";
  EXPECT_EQ(pcds, 2u);
  std::filesystem::remove_all(dir);
}

TEST(Simulate, NoiseFreeReturnsLieOnSurfaces) {
  SimulationSpec spec = make_preset("unstructured");
  spec.sensor.range_noise_sigma_m = 0;
  const Raycaster raycaster(spec.scene);
  const auto dirs = beam_directions(spec.sensor);
  const auto poses = sample_poses(spec.trajectory);
  size_t checked = 0, entering = 0;
  for (size_t i : {0ul, 5ul, 11ul}) {
    ScanCounts counts;
    const Scan scan = simulate_scan(raycaster, spec.sensor, dirs, poses[i], 1, i, counts);
    const Vec3d o{poses[i].position.x, poses[i].position.y, poses[i].position.z};
    for (const Vec3f& pf : scan.points) {
      const Vec3d p{pf.x, pf.y, pf.z};
      const double range = norm(p - o);
      if (range > spec.sensor.max_range_m) continue;
      const Vec3d d = (1.0 / range) * (p - o);
      ASSERT_FALSE(spec.scene.contains(p - 1e-3 * d)) << "a solid before the hit";
      entering += spec.scene.contains(p + 1e-4 * d);
      ++checked;
    }
  }
  EXPECT_GT(checked, 20000u);
  // Just past the hit the beam is inside a solid, except for beams grazing an edge.
  EXPECT_GT(entering, checked * 998 / 1000);
}

TEST(Simulate, NoReturnsAndDropoutsReachTheMapperAsDocumented) {
  SimulationSpec spec = make_preset("unstructured");  // open sky: upper beams find nothing
  spec.sensor.dropout = 0.25;
  const Raycaster raycaster(spec.scene);
  const auto dirs = beam_directions(spec.sensor);
  const Pose pose = sample_poses(spec.trajectory)[3];
  ScanCounts counts;
  const Scan scan = simulate_scan(raycaster, spec.sensor, dirs, pose, 9, 3, counts);
  EXPECT_GT(counts.no_returns, 5000u);
  EXPECT_GT(counts.dropped, 3000u);
  const Vec3d o{pose.position.x, pose.position.y, pose.position.z};
  size_t at_twice_max = 0;
  for (const Vec3f& p : scan.points)
    at_twice_max += std::isfinite(p.x) && std::abs(norm(Vec3d{p.x, p.y, p.z} - o) - 200.0) < 1e-3;
  EXPECT_EQ(at_twice_max, counts.no_returns);

  // Through a PCD file and the mapper's preprocessing with --max-range = the sensor's.
  const auto dir = testing::make_temp_dir("sim-noreturn");
  write_pcd(dir / "s.pcd", scan);
  const Scan back = read_pcd(dir / "s.pcd");
  PreprocessParams params;
  params.max_range_m = spec.sensor.max_range_m;
  params.end_margin_m = 0;
  ScanObservations obs;
  PreprocessCounts pc;
  preprocess_scan(back, params, obs, pc);
  EXPECT_EQ(pc.dropped_nonfinite, counts.dropped);
  EXPECT_EQ(pc.beyond_max_range, counts.no_returns);
  EXPECT_EQ(pc.hits, counts.returns);
  EXPECT_EQ(pc.beams, counts.returns + counts.no_returns);  // every no-return is a free beam
  std::filesystem::remove_all(dir);
}

TEST(Presets, SensorNeverStartsInsideASolid) {
  for (const std::string& name : preset_names()) {
    const SimulationSpec spec = make_preset(name);
    for (const Pose& p : sample_poses(spec.trajectory))
      ASSERT_FALSE(spec.scene.contains({p.position.x, p.position.y, p.position.z})) << name;
  }
  const SimulationSpec campus = make_preset("campus");
  EXPECT_GT(campus.scene.primitives.size(), 2000u);
  EXPECT_EQ(campus.trajectory.scans, 3000);
}

}  // namespace
}  // namespace bgkmap::sim
