// One range scan: world-frame end points and the sensor pose they were taken from.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/core/pose_covariance.hpp"

namespace bgkmap {

// Sensor pose: translation (the beams' origin) and orientation as a unit quaternion.
struct Pose {
  Vec3f position;
  float qw = 1, qx = 0, qy = 0, qz = 0;

  Vec3f rotate(const Vec3f& v) const;     // orientation applied to v
  Vec3f transform(const Vec3f& v) const;  // sensor frame -> world frame
};

struct Scan {
  std::vector<Vec3f> points;  // world frame unless the reader was told otherwise; may hold NaN/Inf
  Pose pose;                  // pose.position is the origin of every beam
  std::string source;         // file the scan came from, for messages
  // The reader already put the points in the world frame (OctoMap .graph nodes), so
  // PreprocessParams::apply_viewpoint must not transform them again.
  bool points_in_world_frame = false;
  // False when the file gives no sensor pose (PLY, XYZ, a PCD without a VIEWPOINT or with PCL's
  // default one): ScanSource then takes it from --poses or --origin, or refuses the scan
  // (scan_pose_rule.hpp); `pose` is only a placeholder until then.
  bool has_own_pose = true;
  // Readings at or beyond this range are the sensor's "no return" code, not surfaces (CARMEN
  // logs: carmen_log.hpp); 0: the format has none. Preprocessing never makes them hits.
  float no_return_range_m = 0;
  // The uncertainty of `pose` (pose_covariance.hpp), from a poses file with covariance; without
  // it PreprocessParams::pose_sigma applies.
  std::optional<PoseCovariance> pose_covariance;
  std::string pose_covariance_source;  // where it came from ("FILE line N"), for messages
};

}  // namespace bgkmap
