#include "bgkmap/io/scan_pose_rule.hpp"

#include <algorithm>
#include <cmath>

#include "bgkmap/io/errors.hpp"

namespace bgkmap {

namespace {
const char* const kNoPoseHelp = "give --origin X,Y,Z or --poses FILE";

std::string flag_names(bool poses, bool origin) { return poses && origin ? "--poses and --origin" : poses ? "--poses" : "--origin"; }
}  // namespace

bool rotates(const Pose& pose) {
  const double vector = std::sqrt(double(pose.qx) * pose.qx + double(pose.qy) * pose.qy + double(pose.qz) * pose.qz);
  return 2 * std::atan2(vector, std::fabs(double(pose.qw))) > 1e-6;
}

ScanPoseRule::ScanPoseRule(const std::filesystem::path& poses_file, const std::optional<Vec3f>& origin,
                           const std::optional<PointFrame>& frame, const std::vector<std::filesystem::path>& files,
                           const OwnPose& own_pose_of)
    : poses_file_(poses_file), origin_(origin), files_(files) {
  if (!gives_poses()) return;
  const std::string flag = flag_names(!poses_file_.empty(), origin_.has_value());
  for (size_t i = 0; i < files_.size(); ++i) {
    const std::string own = own_pose_of(i);
    if (!own.empty())
      throw InputError(files_[i], "has a sensor pose of its own (" + own + ") and " + flag +
                                      " gives one too: " + flag + " is for inputs without one, not both");
  }
  if (poses_file_.empty()) return;
  poses_ = read_pose_list(poses_file_);
  if (poses_.size() != files_.size())
    throw InputError(poses_file_, std::to_string(poses_.size()) + " poses for " + std::to_string(files_.size()) +
                                      " scan files without a pose of their own (one pose a file, in input order)");
  if (frame) return;
  for (size_t i = 0; i < poses_.size(); ++i)
    if (rotates(poses_[i].pose))
      throw InputError(poses_file_, "line " + std::to_string(poses_[i].line) + ": a rotated pose for " +
                                        files_[i].string() +
                                        ", whose points may be world- or sensor-frame: give --frame world or --frame sensor");
}

bool ScanPoseRule::poses_carry_covariances() const {
  return std::any_of(poses_.begin(), poses_.end(), [](const PoseRecord& r) { return r.covariance.has_value(); });
}

void ScanPoseRule::apply(Scan& scan, size_t file, const std::string& own_source) {
  if (!gives_poses()) {
    if (!scan.has_own_pose)
      throw InputError(files_.at(file),
                       "no sensor pose of its own (a PLY or XYZ file, or a PCD without a VIEWPOINT or with PCL's "
                       "default 0 0 0 1 0 0 0): " + std::string(kNoPoseHelp));
    ++sources_[own_source];
    return;
  }
  if (scan.has_own_pose)  // the file changed since the constructor looked
    throw InputError(files_.at(file), "has a sensor pose of its own and " +
                                          flag_names(!poses_file_.empty(), origin_.has_value()) + " gives one too");
  if (!poses_.empty()) {
    const PoseRecord& record = poses_.at(file);
    scan.pose = record.pose;
    scan.pose_covariance = record.covariance;
    if (record.covariance) scan.pose_covariance_source = poses_file_.string() + " line " + std::to_string(record.line);
    ++sources_["--poses"];
  } else {
    scan.pose = Pose{};
    scan.pose.position = *origin_;
    ++sources_["--origin"];
  }
}

}  // namespace bgkmap
