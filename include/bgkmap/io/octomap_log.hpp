// OctoMap's plain-text scan log (the input of OctoMap's log2graph, e.g. its scan.dat):
//   NODE x y z roll pitch yaw
//   x y z          (points in the sensor frame, one a line, until the next NODE)
// One scan per NODE: points transformed to the world by the node's pose (OctoMap's Pose6D:
// roll about x, pitch about y, yaw about z, applied as yaw * pitch * roll), origin = (x, y, z).
// Files .dat, or .log whose first data line is a NODE (other .log files are CARMEN logs); plain
// or gzipped. '#' lines and blank lines are skipped.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>

#include "bgkmap/core/scan.hpp"

namespace bgkmap {

// True when the first line that is not blank or a '#' comment starts with NODE (false for a file
// that cannot be read: the reader chosen then reports why).
bool looks_like_octomap_log(const std::filesystem::path& file);

class OctomapLogReader {
 public:
  // Opens the file; throws InputError naming it when it cannot be opened.
  explicit OctomapLogReader(const std::filesystem::path& file);
  ~OctomapLogReader();
  OctomapLogReader(OctomapLogReader&&) noexcept;
  OctomapLogReader& operator=(OctomapLogReader&&) noexcept;

  // The next node's scan; false after the last. Throws InputError naming the file and line for
  // points before the first NODE, a NODE without six numbers or with a non-finite pose, a point
  // line without three numbers, or a truncated/corrupt gzip stream.
  bool next(Scan& scan);

  // The share of the log read so far, 0 to 1 (of its uncompressed bytes when gzipped).
  double fraction_read() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace bgkmap
