// KITTI odometry sequences, as SemanticKITTI and the KITTI tools lay them out: a folder with
//   velodyne/NNNNNN.bin   float32 x y z reflectance per point (velodyne frame)
//   poses.txt             per scan, 12 numbers: the 3x4 pose [R | t] of camera 0 in the world
//                         (the camera-0 frame of the first scan), row-major
//   calib.txt             a line "Tr: " + 12 numbers, velodyne -> camera 0 (other lines ignored)
// Scan i's velodyne-to-world pose is V_i = P_i * Tr. The map's world is, by default, the velodyne
// frame of the first scan (z up, as KITTI's tools show the clouds): points W * V_i * p with
// W = V_0^-1; with KittiFrame::kCamera it is KITTI's own camera-0 frame of the first scan
// (y down, z forward): P_i * Tr * p. The origin is the translation of the same transform. A
// sequence folder is one input.
#pragma once

#include <array>
#include <filesystem>
#include <system_error>
#include <vector>

#include "bgkmap/core/params.hpp"
#include "bgkmap/core/scan.hpp"

namespace bgkmap {

// True for a folder holding velodyne/ and calib.txt.
bool is_kitti_sequence(const std::filesystem::path& folder);

// The scans of a sequence folder, velodyne/*.bin in natural order; `ec` says why it could not be listed.
std::vector<std::filesystem::path> kitti_scan_files(const std::filesystem::path& folder, std::error_code& ec);

class KittiSequenceReader {
 public:
  // Reads calib.txt and poses.txt and lists velodyne/*.bin (natural order). Throws InputError
  // naming the file (and line) for a missing file, a malformed line, a missing Tr, or a number
  // of poses that differs from the number of scans.
  explicit KittiSequenceReader(const std::filesystem::path& folder, KittiFrame frame = KittiFrame::kVelodyne);

  size_t size() const { return scans_.size(); }

  // The next scan; false after the last. Throws InputError naming the .bin file when its size is
  // not a whole number of 16-byte points.
  bool next(Scan& scan);

 private:
  using Matrix34 = std::array<double, 12>;
  std::vector<std::filesystem::path> scans_;
  std::vector<Matrix34> velodyne_to_world_;  // W * P_i * Tr (W: identity in the camera frame)
  size_t next_ = 0;
};

}  // namespace bgkmap
