// Where the sensor is for each scan: a path through waypoints, or one pose held (station keeping).
#pragma once

#include <optional>
#include <vector>

#include "bgkmap/core/scan.hpp"
#include "bgkmap/sim/vec_math.hpp"

namespace bgkmap::sim {

struct Waypoint {
  Vec3d position;
  std::optional<double> yaw_deg;  // heading about z; absent: face the direction of travel
};

struct Trajectory {
  // One waypoint: station keeping, the same pose `scans` times (yaw 0 unless given). Several:
  // `scans` poses evenly spaced by distance along the polyline, first and last waypoint
  // included; a closed path returns to the first waypoint and spaces the poses around the loop.
  std::vector<Waypoint> waypoints;
  bool closed = false;
  int scans = 1;

  // Throws std::invalid_argument with a one-line reason (no waypoints, scans < 1, yaw given on
  // some waypoints only, a path of zero length with several scans).
  void validate() const;
};

// Yaw interpolated along each segment (shortest way round) when the waypoints give it; else the
// heading of the segment being travelled. Orientation is yaw only (the sensor is kept level).
std::vector<Pose> sample_poses(const Trajectory& trajectory);

Pose pose_from_yaw(const Vec3d& position, double yaw_deg);

}  // namespace bgkmap::sim
