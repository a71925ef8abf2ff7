// Where scans come from: files (.pcd, OctoMap .graph, CARMEN logs) and folders of them, read one
// file at a time (a .graph one node at a time, a log one line at a time) so that thousands of
// scans never sit in memory together.
#pragma once

#include <cstddef>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "bgkmap/core/scan.hpp"
#include "bgkmap/io/carmen_log.hpp"
#include "bgkmap/io/scan_graph_io.hpp"

namespace bgkmap {

// Orders file names the way people number scans: "scan_2" before "scan_10". Runs of digits
// compare by value, everything else byte by byte; names equal that way ("a01", "a1") fall back
// to plain string order, so this is a strict total order.
bool natural_less(const std::string& a, const std::string& b);

enum class ScanFileType {
  kPcd,    // points as stored, world frame unless PreprocessParams::apply_viewpoint
  kGraph,  // OctoMap scan graph: the reader returns world-frame points (see scan_graph_io.hpp)
  kCarmenLog,  // CARMEN laser log, plain or gzipped: one planar scan per laser line (carmen_log.hpp)
};

// From the extension (case-insensitive); throws InputError naming the file for anything else.
ScanFileType scan_file_type(const std::filesystem::path& file);

class ScanSource {
 public:
  // Expands folders (their scan files of the types above, natural order, not recursive; other files are
  // skipped) and checks every input exists and has a supported extension. Throws InputError
  // naming the offending path: a missing path, an unsupported file type (e.g. an OctoMap .bt
  // map), a folder with no scan files, or no inputs at all.
  explicit ScanSource(const std::vector<std::filesystem::path>& inputs);

  const std::vector<std::filesystem::path>& files() const { return files_; }

  // The next scan, or false after the last. A .graph file yields one scan per node (see
  // scan_graph_io.hpp), a CARMEN log one per laser message; a .pcd file one scan, which may be
  // empty. Throws InputError naming the
  // file when one cannot be read; the source can not be resumed after that.
  bool next(Scan& scan);

  // Messages the readers skipped as carrying no scan (CARMEN ODOM, PARAM, ...), by type, summed
  // over the files read so far.
  const std::map<std::string, uint64_t>& skipped_messages() const { return skipped_; }

 private:
  std::vector<std::filesystem::path> files_;
  size_t next_file_ = 0;
  std::optional<ScanGraphReader> graph_;  // the .graph file being read, node by node
  std::optional<CarmenLogReader> carmen_;  // the CARMEN log being read, line by line
  std::map<std::string, uint64_t> skipped_;
};

}  // namespace bgkmap
