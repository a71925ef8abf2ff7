// Sensor models and simulated scans: a planar scan of one wall lands where geometry says; noise
// and dropout have the stated statistics and are reproducible from the seed.
#include <gtest/gtest.h>

#include <cmath>

#include "bgkmap/sim/scanner.hpp"
#include "bgkmap/sim/trajectory.hpp"

namespace bgkmap::sim {
namespace {

constexpr double kDeg = M_PI / 180;

TEST(Sensor, PresetBeamPatterns) {
  const auto vlp = beam_directions(sensor_preset("vlp16"));
  ASSERT_EQ(vlp.size(), 16u * 1800u);
  EXPECT_NEAR(std::asin(vlp.front().z) / kDeg, -15, 1e-9);  // first ring: lowest
  EXPECT_NEAR(std::asin(vlp.back().z) / kDeg, 15, 1e-9);
  EXPECT_NEAR(std::asin(vlp[1800].z) / kDeg, -13, 1e-9);     // 2 degrees between rings
  EXPECT_NEAR(std::atan2(vlp[1].y, vlp[1].x) - std::atan2(vlp[0].y, vlp[0].x), 0.2 * kDeg, 1e-12);
  for (const Vec3d& d : vlp) ASSERT_NEAR(norm(d), 1.0, 1e-12);

  const auto planar = beam_directions(sensor_preset("planar"));
  ASSERT_EQ(planar.size(), 1081u);  // 270 / 0.25 + 1: both edges
  EXPECT_NEAR(std::atan2(planar.front().y, planar.front().x) / kDeg, -135, 1e-9);
  EXPECT_NEAR(std::atan2(planar.back().y, planar.back().x) / kDeg, 135, 1e-9);
  for (const Vec3d& d : planar) ASSERT_EQ(d.z, 0.0);

  const SensorModel camera = sensor_preset("depth-camera");
  const auto pixels = beam_directions(camera);
  ASSERT_EQ(pixels.size(), 160u * 120u);
  // The outer pixel centres sit half a pixel inside the field of view.
  const double fx = 80 / std::tan(43.5 * kDeg);
  EXPECT_NEAR(std::atan2(pixels[0].y, pixels[0].x), std::atan(79.5 / fx), 1e-12);  // top-left looks left...
  EXPECT_GT(pixels[0].z, 0);                                                      // ...and up
  EXPECT_LT(pixels.back().y, 0);
  EXPECT_LT(pixels.back().z, 0);
}

TEST(Sensor, CustomSensorsAreValidated) {
  SensorModel s = sensor_preset("vlp16");
  s.rings = 0;
  EXPECT_THROW(s.validate(), std::invalid_argument);
  s = sensor_preset("vlp16");
  s.dropout = 1.5;
  EXPECT_THROW(s.validate(), std::invalid_argument);
  s = sensor_preset("vlp16");
  s.elevation_min_deg = 20;
  EXPECT_THROW(s.validate(), std::invalid_argument);
  EXPECT_THROW(sensor_preset("kinect"), std::invalid_argument);
}

// A wall x in [5, 5.2], |y| <= 50, |z| <= 1, seen by a noise-free planar scanner at the origin.
Scene wall_scene() {
  Scene scene;
  scene.primitives.push_back(Box({5.1, 0, 0}, {0.2, 100, 2}));
  return scene;
}

TEST(Scanner, PlanarScanOfAWallHitsWhereGeometrySays) {
  const Scene scene = wall_scene();
  const Raycaster raycaster(scene);
  SensorModel sensor = sensor_preset("planar");
  sensor.range_noise_sigma_m = 0;
  const auto dirs = beam_directions(sensor);
  ScanCounts counts;
  const Scan scan = simulate_scan(raycaster, sensor, dirs, pose_from_yaw({0, 0, 0}, 0), 1, 0, counts);
  ASSERT_EQ(scan.points.size(), 1081u);
  uint64_t expected_returns = 0;
  for (size_t k = 0; k < dirs.size(); ++k) {
    const double azimuth = (-135 + 0.25 * k) * kDeg;
    const double range = 5 / std::cos(azimuth);
    const Vec3f& p = scan.points[k];
    if (std::cos(azimuth) > 0 && range <= 30) {
      ++expected_returns;
      EXPECT_NEAR(p.x, 5.0, 1e-5) << k;
      EXPECT_NEAR(p.y, 5 * std::tan(azimuth), 1e-4) << k;
    } else {  // no return: 2 x 30 m along the beam
      EXPECT_NEAR(p.x, 60 * std::cos(azimuth), 1e-4) << k;
      EXPECT_NEAR(p.y, 60 * std::sin(azimuth), 1e-4) << k;
    }
    EXPECT_EQ(p.z, 0.0f);
  }
  // |azimuth| <= acos(5/30) = 80.4 deg: 643 beams.
  EXPECT_EQ(expected_returns, 643u);
  EXPECT_EQ(counts.returns, expected_returns);
  EXPECT_EQ(counts.no_returns, 1081u - expected_returns);
  EXPECT_EQ(counts.dropped, 0u);
}

TEST(Scanner, PoseMovesAndTurnsTheBeams) {
  // The same wall seen from (2, -1, 0.5) facing +y: the wall is now to the scanner's right.
  const Scene scene = wall_scene();
  const Raycaster raycaster(scene);
  SensorModel sensor = sensor_preset("planar");
  sensor.range_noise_sigma_m = 0;
  const auto dirs = beam_directions(sensor);
  ScanCounts counts;
  const Scan scan = simulate_scan(raycaster, sensor, dirs, pose_from_yaw({2, -1, 0.5}, 90), 1, 0, counts);
  EXPECT_EQ(scan.pose.position.x, 2.0f);
  // Beam at sensor azimuth -90 deg (index 180) points along world +x: hits (5, -1, 0.5).
  EXPECT_NEAR(scan.points[180].x, 5.0, 1e-5);
  EXPECT_NEAR(scan.points[180].y, -1.0, 1e-5);
  EXPECT_NEAR(scan.points[180].z, 0.5, 1e-6);
  // Sensor azimuth -135 deg points along world (1, -1)/sqrt(2): hits (5, -4, 0.5).
  EXPECT_NEAR(scan.points[0].x, 5.0, 1e-5);
  EXPECT_NEAR(scan.points[0].y, -4.0, 1e-4);
  // Sensor azimuth +90 deg points along world -x: no return at 60 m.
  EXPECT_NEAR(scan.points[900].x, 2 - 60.0, 1e-4);
}

// Many beams at the wall: ranges 5 / cos(azimuth) for |azimuth| <= 30 deg.
struct NoisyRun {
  std::vector<Scan> scans;
  ScanCounts counts;
};

NoisyRun noisy_wall_scans(uint64_t seed, double sigma, double dropout) {
  static const Scene scene = wall_scene();
  static const Raycaster raycaster(scene);
  SensorModel sensor = sensor_preset("planar");
  sensor.horizontal_fov_deg = 60;
  sensor.azimuth_resolution_deg = 0.01;
  sensor.range_noise_sigma_m = sigma;
  sensor.dropout = dropout;
  const auto dirs = beam_directions(sensor);
  NoisyRun run;
  for (int s = 0; s < 10; ++s)
    run.scans.push_back(simulate_scan(raycaster, sensor, dirs, pose_from_yaw({0, 0, 0}, 0), seed, s, run.counts));
  return run;
}

TEST(Scanner, NoiseAndDropoutHaveTheirStatistics) {
  const double sigma = 0.05, dropout = 0.2;
  const NoisyRun run = noisy_wall_scans(42, sigma, dropout);
  double sum = 0, sum2 = 0, within_one_sigma = 0;
  uint64_t n = 0, nan = 0, total = 0;
  for (const Scan& scan : run.scans)
    for (const Vec3f& p : scan.points) {
      ++total;
      if (std::isnan(p.x)) {
        ++nan;
        continue;
      }
      const double azimuth = std::atan2(p.y, p.x);
      const double error = std::hypot(p.x, p.y) - 5 / std::cos(azimuth);
      sum += error;
      sum2 += error * error;
      within_one_sigma += std::abs(error) <= sigma;
      ++n;
    }
  ASSERT_EQ(total, 60010u);
  EXPECT_EQ(nan, run.counts.dropped);
  EXPECT_EQ(n, run.counts.returns);
  // Binomial and Gaussian sampling errors, 5 standard errors wide.
  EXPECT_NEAR(double(nan) / total, dropout, 5 * std::sqrt(dropout * (1 - dropout) / total));
  const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
  EXPECT_NEAR(mean, 0.0, 5 * sigma / std::sqrt(double(n)));
  EXPECT_NEAR(sd, sigma, 5 * sigma / std::sqrt(2.0 * n));
  EXPECT_NEAR(within_one_sigma / n, 0.682689, 5 * std::sqrt(0.2166 / n));
}

TEST(Scanner, NoiseIsReproducibleFromTheSeed) {
  const NoisyRun a = noisy_wall_scans(7, 0.03, 0.1), b = noisy_wall_scans(7, 0.03, 0.1), c = noisy_wall_scans(8, 0.03, 0.1);
  size_t differ = 0;
  for (size_t s = 0; s < a.scans.size(); ++s)
    for (size_t k = 0; k < a.scans[s].points.size(); ++k) {
      const Vec3f &pa = a.scans[s].points[k], &pb = b.scans[s].points[k], &pc = c.scans[s].points[k];
      if (std::isnan(pa.x)) {
        ASSERT_TRUE(std::isnan(pb.x));
      } else {
        ASSERT_EQ(pa.x, pb.x);
        ASSERT_EQ(pa.y, pb.y);
      }
      differ += std::isnan(pa.x) != std::isnan(pc.x) || (!std::isnan(pa.x) && pa.x != pc.x);
    }
  EXPECT_GT(differ, a.scans.size() * a.scans[0].points.size() / 2);  // another seed, other noise
  // Scans of one run differ from each other too (the scan index is part of the stream).
  EXPECT_NE(a.scans[0].points[3000].x, a.scans[1].points[3000].x);
}

TEST(Trajectory, WaypointsAreSampledEvenlyByDistance) {
  Trajectory t;
  t.waypoints = {{{0, 0, 1}, std::nullopt}, {{4, 0, 1}, std::nullopt}, {{4, 2, 1}, std::nullopt}};
  t.scans = 4;  // 6 m long, open: every 2 m
  const auto poses = sample_poses(t);
  ASSERT_EQ(poses.size(), 4u);
  const double expected[4][2] = {{0, 0}, {2, 0}, {4, 0}, {4, 2}};
  for (int k = 0; k < 4; ++k) {
    EXPECT_NEAR(poses[k].position.x, expected[k][0], 1e-6);
    EXPECT_NEAR(poses[k].position.y, expected[k][1], 1e-6);
    EXPECT_NEAR(poses[k].position.z, 1, 1e-6);
  }
  // Facing the direction of travel: yaw 0 on the first leg, 90 deg on the second.
  EXPECT_NEAR(poses[1].qz, 0, 1e-7);
  EXPECT_NEAR(poses[3].qz, std::sin(M_PI / 4), 1e-6);

  t.closed = true;  // 4 + 2 + sqrt(20) around the loop, 4 poses
  const auto loop = sample_poses(t);
  const double spacing = (6 + std::sqrt(20.0)) / 4;
  EXPECT_NEAR(loop[1].position.x, spacing, 1e-5);
  EXPECT_NEAR(loop[2].position.y, 2 * spacing - 4, 1e-5);

  Trajectory turning = t;  // yaw given: interpolated the short way round (350 -> 10 via 0)
  turning.closed = false;
  turning.waypoints = {{{0, 0, 0}, 350.0}, {{2, 0, 0}, 10.0}};
  turning.scans = 3;
  const auto turned = sample_poses(turning);
  EXPECT_NEAR(turned[1].qw, 1.0, 1e-7);  // yaw 0 halfway

  Trajectory station;
  station.waypoints = {{{1, 2, 3}, 45.0}};
  station.scans = 5;
  const auto held = sample_poses(station);
  ASSERT_EQ(held.size(), 5u);
  EXPECT_EQ(held[4].position.y, 2.0f);
  EXPECT_NEAR(held[4].qz, std::sin(M_PI / 8), 1e-7);

  Trajectory mixed = t;
  mixed.waypoints[0].yaw_deg = 0;
  EXPECT_THROW(mixed.validate(), std::invalid_argument);
}

}  // namespace
}  // namespace bgkmap::sim
