// Where scans come from: files (.pcd, OctoMap .graph) and folders of them, read one scan at a
// time so that thousands of scans never sit in memory together.
#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <vector>

#include "bgkmap/core/scan.hpp"

namespace bgkmap {

// Orders file names the way people number scans: "scan_2" before "scan_10".
bool natural_less(const std::string& a, const std::string& b);

class ScanSource {
 public:
  // Expands folders (their .pcd and .graph files, natural order, not recursive) and checks every
  // input exists and has a supported extension; throws InputError naming the offending path.
  explicit ScanSource(const std::vector<std::filesystem::path>& inputs);
  ~ScanSource();
  ScanSource(ScanSource&&) noexcept;
  ScanSource& operator=(ScanSource&&) noexcept;

  const std::vector<std::filesystem::path>& files() const { return files_; }

  // The next scan, or false after the last. A .graph file yields one scan per node (points
  // transformed to the world frame by the node pose, origin = node position). Throws InputError
  // naming the file when one cannot be read.
  bool next(Scan& scan);

 private:
  std::vector<std::filesystem::path> files_;
  size_t next_file_ = 0;
  std::vector<Scan> pending_;  // remaining nodes of the current .graph file
};

}  // namespace bgkmap
