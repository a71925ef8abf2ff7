// The one rule for a scan's sensor pose, whatever its format (docs/USAGE.md, "Poses"):
// - a scan whose file gives a pose (Scan::has_own_pose: a PCD's VIEWPOINT other than PCL's
//   default, a .graph node, a CARMEN laser line, an OctoMap log NODE, KITTI's poses.txt) keeps it,
//   and --poses or --origin beside such a file is a conflict, refused naming the file and the flag;
// - a scan without one (PLY, XYZ, a PCD without a VIEWPOINT or with PCL's default) takes line i of
//   --poses (the i-th input file) or --origin, and without either is refused naming both flags;
// - a rotated --poses line leaves open whether the points are world- or sensor-frame, so without
//   --frame it is refused naming --frame.
// A new reader plugs in by setting Scan::has_own_pose and naming its pose field (own_pose_of).
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "bgkmap/core/scan.hpp"
#include "bgkmap/io/pose_list.hpp"

namespace bgkmap {

// The frame of the points a file holds, where its format does not say (--frame).
enum class PointFrame { kWorld, kSensor };

class ScanPoseRule {
 public:
  // What gives files[i]'s scans a pose of their own ("VIEWPOINT", "its NODE lines"), or "" for a
  // file without one. Asked only when --poses or --origin is given.
  using OwnPose = std::function<std::string(size_t file)>;

  // Reads `poses_file` (if given) and refuses, as InputError naming the file (and line): a file
  // with a pose of its own beside --poses/--origin, a pose count other than the file count, and a
  // rotated pose with no `frame`.
  ScanPoseRule(const std::filesystem::path& poses_file, const std::optional<Vec3f>& origin,
               const std::optional<PointFrame>& frame, const std::vector<std::filesystem::path>& files,
               const OwnPose& own_pose_of);

  // Gives `scan`, read from files[file], its pose by the rule (and a --poses line's covariance),
  // and counts where it came from; `own_source` names the file's own pose field for the count.
  // Throws InputError naming the file when the scan has no pose and no flag gives one.
  void apply(Scan& scan, size_t file, const std::string& own_source);

  bool gives_poses() const { return !poses_file_.empty() || origin_.has_value(); }
  bool poses_carry_covariances() const;
  // Scans given a pose so far, by where it came from ("--poses", "--origin", "PCD VIEWPOINT", ...).
  const std::map<std::string, uint64_t>& sources() const { return sources_; }

 private:
  std::filesystem::path poses_file_;
  std::optional<Vec3f> origin_;
  std::vector<std::filesystem::path> files_;
  std::vector<PoseRecord> poses_;  // poses_file_, read: line i for files_[i]
  std::map<std::string, uint64_t> sources_;
};

// Whether `pose` turns its points (more than 1e-6 rad): a --poses line that does leaves the
// points' frame to --frame.
bool rotates(const Pose& pose);

}  // namespace bgkmap
