// Where scans come from: files (.pcd, OctoMap .graph, CARMEN logs, ROS bags) and folders of them,
// read one file at a time (a .graph one node at a time, a log one line at a time, a bag one
// message at a time) so that thousands of scans never sit in memory together.
#pragma once

#include <cstddef>
#include <exception>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "bgkmap/core/scan.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/carmen_log.hpp"
#include "bgkmap/io/kitti_io.hpp"
#include "bgkmap/io/octomap_log.hpp"
#include "bgkmap/io/pose_list.hpp"
#include "bgkmap/io/rosbag_reader.hpp"
#include "bgkmap/io/scan_pose_rule.hpp"
#include "bgkmap/io/scan_graph_io.hpp"

namespace bgkmap {

// Orders file names the way people number scans: "scan_2" before "scan_10". Runs of digits
// compare by value, everything else byte by byte; names equal that way ("a01", "a1") fall back
// to plain string order, so this is a strict total order.
bool natural_less(const std::string& a, const std::string& b);

enum class ScanFileType {
  kPcd,    // points as stored, world frame unless PreprocessParams::apply_viewpoint (--frame sensor)
  kGraph,  // OctoMap scan graph: the reader returns world-frame points (see scan_graph_io.hpp)
  kCarmenLog,  // CARMEN laser log, plain or gzipped: one planar scan per laser line (carmen_log.hpp)
  kOctomapLog,  // OctoMap text scan log (.dat, or a .log starting with NODE): one scan per NODE
  kPly,         // PLY, no pose of its own (point_text_io.hpp): ScanSourceOptions gives it
  kXyz,         // XYZ text, likewise
  kKittiSequence,  // a KITTI odometry sequence folder (kitti_io.hpp)
  kRosbag,         // a ROS 1 bag: one scan per message of ScanSourceOptions::topics (rosbag_reader.hpp)
};

// From the extension (case-insensitive; a .log file by its first line, CARMEN or OctoMap; a
// folder holding velodyne/ and calib.txt is a KITTI sequence); throws InputError naming the file
// for anything else.
ScanFileType scan_file_type(const std::filesystem::path& file);

// Sensor poses of inputs that have none of their own (PLY, XYZ, PCD without a VIEWPOINT or with
// PCL's default; the rule: scan_pose_rule.hpp): the i-th input file takes the pose on data line i
// of `poses` (TUM format, as `bgkmap simulate`'s poses.txt), or else every one the origin `origin`
// (identity orientation). Their points are world-frame unless PreprocessParams::apply_viewpoint
// says they are sensor-frame; `frame` is what --frame said, if anything (a rotated pose needs it).
// A pose line with a covariance (pose_list.hpp) gives that scan's Scan::pose_covariance.
// `kitti_frame`: the world KITTI sequences are mapped in (kitti_io.hpp).
// `pose_covariance`: a poses file with a covariance on every line, one line per scan of any
// format in input order; each line's position must be the scan's origin (within 1 mm), and the
// file must hold exactly as many lines as there are scans (InputError naming it otherwise).
// ROS bags: `topics` are read, each message posed by /tf in `tf_frame` (a pose of the bag's own,
// so --poses and --origin beside it are refused), or else, when every input is a bag, by the
// next line of `poses`, one a message (--frame does not apply: a message's points are in its
// header.frame_id).
struct ScanSourceOptions {
  std::filesystem::path poses;
  std::optional<Vec3f> origin;
  std::filesystem::path pose_covariance;
  std::optional<PointFrame> frame;
  KittiFrame kitti_frame = KittiFrame::kVelodyne;
  std::vector<std::string> topics{};  // (initialised: brace lists of the fields above stay warning-free)
  std::string tf_frame{};
};
// How many scans a ScanSource has returned (held ones passed over included) out of how many its
// inputs hold: known for PCD, PLY and XYZ files, KITTI folders, and .graph files and bags once
// opened; estimated from the bytes read for logs (and from the scans per byte so far for files
// not yet opened), and exact once every input is read.
struct ScanProgress {
  uint64_t done = 0, total = 0;
  bool estimated = false;
};

class ScanSource {
 public:
  // Expands folders (a KITTI sequence folder is one input; other folders: their scan files of
  // the types above, natural order, not recursive; other files are
  // skipped) and checks every input exists and has a supported extension. Throws InputError
  // naming the offending path: a missing path, an unsupported file type (e.g. an OctoMap .bt
  // map), a folder with no scan files, or no inputs at all.
  // The pose rule's refusals that need no scan read (scan_pose_rule.hpp) are made here: PLY/XYZ
  // inputs without --poses or --origin, a file with a pose of its own beside them (a PCD's header
  // is read to tell), a pose count other than the file count, a rotated pose without `frame`.
  // ROS bags: one without --tf-frame needs --poses (and every input a bag, the line count the
  // bags' message count); --topic or --tf-frame without a bag throws std::invalid_argument.
  explicit ScanSource(const std::vector<std::filesystem::path>& inputs, const ScanSourceOptions& options = {});

  const std::vector<std::filesystem::path>& files() const { return files_; }
  // Whether scans come with covariances of their own (--pose-covariance, or --poses lines that
  // carry one).
  bool carries_pose_covariances() const;

  // The next scan, or false after the last. A .graph file yields one scan per node (see
  // scan_graph_io.hpp), a CARMEN log one per laser message, a bag one per message of the topics;
  // a .pcd file one scan, which may be empty. Throws InputError naming the file when one cannot be
  // read; the next call goes on with the file after it, except after a RosbagMessageError (one
  // message of a bag), when it goes on with the bag's next message.
  bool next(Scan& scan);

  // Scans returned so far by where their pose came from ("--poses", "PCD VIEWPOINT", ...).
  const std::map<std::string, uint64_t>& pose_sources() const { return pose_rule_->sources(); }

  // Messages the readers skipped as carrying no scan (CARMEN ODOM, PARAM, ...), by type, summed
  // over the files read so far.
  const std::map<std::string, uint64_t>& skipped_messages() const { return skipped_; }

  // Where the scan next() returned last came from: its file (an index into files()) and its
  // place in that file (0 for a .pcd; the node's or laser message's, in order, for a .graph or
  // a CARMEN log).
  size_t last_file() const { return last_file_; }
  uint64_t last_scan() const { return last_scan_; }

  // How far next() has come (call it on next()'s thread).
  ScanProgress progress() const;

  // Before the first next(): the first held[i] scans of files()[i] are passed over (a resumed
  // map holds them; a .graph's or log's earlier scans are still read to reach the rest).
  void skip_held(std::vector<uint64_t> held) { held_ = std::move(held); }

 private:
  uint64_t held(size_t file) const { return file < held_.size() ? held_[file] : 0; }
  bool streaming() const { return graph_ || carmen_ || octomap_log_ || kitti_ || rosbag_; }
  uint64_t open_stream_size() const;        // the open reader's scans in all, 0 for a log
  double open_stream_fraction_read() const;  // the share of a log read so far

  std::vector<std::filesystem::path> files_;
  size_t next_file_ = 0;
  std::optional<ScanGraphReader> graph_;  // the .graph file being read, node by node
  std::optional<CarmenLogReader> carmen_;  // the CARMEN log being read, line by line
  std::optional<OctomapLogReader> octomap_log_;
  std::optional<KittiSequenceReader> kitti_;
  std::optional<RosbagReader> rosbag_;
  ScanSourceOptions options_;
  // Gives `scan` (the next in input order, held or not) its line of options_.pose_covariance.
  void attach_covariance(Scan& scan);
  InputError covariance_lines_lost(const std::exception& failure) const;
  void check_bag_poses(bool all_bags);

  std::optional<ScanPoseRule> pose_rule_;
  std::vector<PoseRecord> covariances_;  // options_.pose_covariance, read
  uint64_t scans_seen_ = 0;              // scans in input order so far, held ones included
  std::vector<PoseRecord> bag_poses_;  // --poses of inputs that are all bags: a line a message
  size_t next_bag_pose_ = 0;           // bag messages given a line of bag_poses_ so far
  std::map<std::string, uint64_t> skipped_;
  size_t stream_file_ = 0;    // the file (or KITTI folder) the open stream reader reads
  uint64_t stream_scan_ = 0;  // its next scan
  size_t last_file_ = 0;
  uint64_t last_scan_ = 0;
  std::vector<uint64_t> held_;
  std::vector<uint64_t> file_bytes_;     // each input's size (0 for a KITTI folder)
  std::vector<uint64_t> expected_scans_;  // known before reading: 1 a scan file, a KITTI folder's .bin; else 0
  std::vector<uint64_t> file_scans_;     // scans read of each file that is done with
};

}  // namespace bgkmap
