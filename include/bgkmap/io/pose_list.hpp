// Poses files: one sensor pose a data line, TUM format "time x y z qx qy qz qw" (time ignored,
// quaternion normalised; as `bgkmap simulate`'s poses.txt), optionally followed by the pose's
// covariance (pose_covariance.hpp): 9 numbers, a 3x3 row-major over (x, y, yaw), or 36, a 6x6
// row-major over (x, y, z, roll, pitch, yaw); metres and radians. '#' lines are comments.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <vector>

#include "bgkmap/core/pose_covariance.hpp"
#include "bgkmap/core/scan.hpp"

namespace bgkmap {

struct PoseRecord {
  Pose pose;
  std::optional<PoseCovariance> covariance;  // when the line carries one
  uint64_t line = 0;                         // 1-based, for messages
};

// Throws InputError naming the file and line for a malformed line (a field count other than 8,
// 17 or 44, a field that is not a finite number, a zero quaternion, a covariance that fails
// pose_covariance_problem: not symmetric positive semi-definite, or too large to be meant).
std::vector<PoseRecord> read_pose_list(const std::filesystem::path& file);

}  // namespace bgkmap
