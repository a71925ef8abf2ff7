#include "bgkmap/io/scan_source.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/pcd_io.hpp"
#include "bgkmap/io/point_text_io.hpp"

namespace bgkmap {

namespace {
bool is_digit(char c) { return c >= '0' && c <= '9'; }

// Compares the digit runs a[i..) and b[j..) by value and advances past them; <0, 0 or >0.
int compare_numbers(const std::string& a, size_t& i, const std::string& b, size_t& j) {
  while (i < a.size() && a[i] == '0') ++i;  // leading zeros do not change the value
  while (j < b.size() && b[j] == '0') ++j;
  const size_t a_start = i, b_start = j;
  while (i < a.size() && is_digit(a[i])) ++i;
  while (j < b.size() && is_digit(b[j])) ++j;
  if (i - a_start != j - b_start) return i - a_start < j - b_start ? -1 : 1;
  return a.compare(a_start, i - a_start, b, b_start, j - b_start);
}

std::string lower_extension(const std::filesystem::path& file) {
  std::string ext = file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

// The extension without a trailing .gz ("a.xyz.gz" -> ".xyz").
std::string inner_extension(const std::filesystem::path& file) {
  const std::string ext = lower_extension(file);
  return ext == ".gz" ? lower_extension(file.stem()) : ext;
}

bool is_scan_file(const std::filesystem::path& file) {
  const std::string ext = lower_extension(file), inner = inner_extension(file);
  return ext == ".pcd" || ext == ".graph" || ext == ".ply" || inner == ".xyz" || inner == ".dat" ||
         is_carmen_log_name(file) || is_rosbag_name(file);
}

bool holds_one_scan(ScanFileType type) {
  return type == ScanFileType::kPcd || type == ScanFileType::kPly || type == ScanFileType::kXyz;
}

// The field that gives a file of this type its pose, for messages and the report's counts.
const char* own_pose_field(ScanFileType type) {
  switch (type) {
    case ScanFileType::kPcd: return "PCD VIEWPOINT";
    case ScanFileType::kGraph: return ".graph nodes";
    case ScanFileType::kCarmenLog: return "CARMEN laser lines";
    case ScanFileType::kOctomapLog: return "OctoMap log NODE lines";
    case ScanFileType::kKittiSequence: return "KITTI poses.txt";
    case ScanFileType::kRosbag: return "ROS bag /tf";
    case ScanFileType::kPly:
    case ScanFileType::kXyz: break;
  }
  return "";
}

// What gives `file` a pose of its own, or "" when it has none (a PCD by its header).
std::string own_pose_of(const std::filesystem::path& file, ScanFileType type, const ScanSourceOptions& options) {
  if (type == ScanFileType::kPcd) return pcd_has_viewpoint(file) ? "a VIEWPOINT" : "";
  if (type == ScanFileType::kRosbag) return options.tf_frame.empty() ? "" : "/tf in --tf-frame";
  return own_pose_field(type);
}

// The pose source of a bag's messages: /tf in --tf-frame, else their lines of the poses file.
RosbagPoseSource bag_pose_source(const ScanSourceOptions& options, const std::vector<PoseRecord>& poses, size_t first,
                                 uint64_t count) {
  RosbagPoseSource source;
  source.tf_frame = options.tf_frame;
  if (options.tf_frame.empty()) {
    const size_t end = std::min(poses.size(), first + count), begin = std::min(first, end);
    source.poses.assign(poses.begin() + static_cast<std::ptrdiff_t>(begin), poses.begin() + static_cast<std::ptrdiff_t>(end));
    source.poses_file = options.poses;
  }
  return source;
}

std::vector<std::filesystem::path> scan_files_in(const std::filesystem::path& folder) {
  std::vector<std::filesystem::path> files;
  std::error_code ec;
  for (std::filesystem::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code type_ec;
    if (it->is_regular_file(type_ec) && is_scan_file(it->path())) files.push_back(it->path());
  }
  if (ec) throw InputError(folder, "cannot list folder (" + ec.message() + ")");
  std::sort(files.begin(), files.end(), [](const std::filesystem::path& a, const std::filesystem::path& b) {
    return natural_less(a.filename().string(), b.filename().string());
  });
  return files;
}

// Runs `read`, a read of a file holding one scan; when it fails, the scan still counts in `seen`
// (its covariance line is passed over with it, so the next file keeps its own).
template <typename Read>
void read_counting_failures(uint64_t& seen, Read&& read) {
  try {
    read();
  } catch (...) {
    ++seen;
    throw;
  }
}
}  // namespace

bool natural_less(const std::string& a, const std::string& b) {
  size_t i = 0, j = 0;
  while (i < a.size() && j < b.size()) {
    if (is_digit(a[i]) && is_digit(b[j])) {
      const int c = compare_numbers(a, i, b, j);
      if (c != 0) return c < 0;
      continue;
    }
    if (a[i] != b[j]) return static_cast<unsigned char>(a[i]) < static_cast<unsigned char>(b[j]);
    ++i;
    ++j;
  }
  if ((i < a.size()) != (j < b.size())) return j < b.size();  // a is a prefix of b
  return a < b;  // equal up to leading zeros
}

ScanFileType scan_file_type(const std::filesystem::path& file) {
  std::error_code ec;
  if (std::filesystem::is_directory(file, ec)) {
    if (is_kitti_sequence(file)) return ScanFileType::kKittiSequence;
    throw InputError(file, "a folder, not a scan file (nor a KITTI sequence: velodyne/ and calib.txt)");
  }
  const std::string ext = lower_extension(file), inner = inner_extension(file);
  if (ext == ".pcd") return ScanFileType::kPcd;
  if (ext == ".graph") return ScanFileType::kGraph;
  if (ext == ".ply") return ScanFileType::kPly;
  if (inner == ".xyz") return ScanFileType::kXyz;
  if (inner == ".dat") return ScanFileType::kOctomapLog;
  if (is_rosbag_name(file)) return ScanFileType::kRosbag;
  if (is_carmen_log_name(file)) return looks_like_octomap_log(file) ? ScanFileType::kOctomapLog : ScanFileType::kCarmenLog;
  const std::string hint = ext == ".bt" || ext == ".ot" ? " (an OctoMap map, not a scan)" : "";
  throw InputError(file, "unsupported scan file type '" + ext + "'" + hint +
                             "; expected .pcd, .graph, .ply, .xyz, a CARMEN log (.log, .clf), an OctoMap log (.dat), "
                             "a ROS 1 bag (.bag) or a KITTI sequence folder");
}

ScanSource::ScanSource(const std::vector<std::filesystem::path>& inputs, const ScanSourceOptions& options)
    : options_(options) {
  if (inputs.empty()) throw InputError("(no inputs)", "no scan files or folders given");
  for (const std::filesystem::path& input : inputs) {
    std::error_code ec;
    const std::filesystem::file_status status = std::filesystem::status(input, ec);
    if (std::filesystem::is_directory(status)) {
      if (is_kitti_sequence(input)) {
        files_.push_back(input);
        continue;
      }
      std::vector<std::filesystem::path> found = scan_files_in(input);
      if (found.empty()) throw InputError(input, "folder holds no scan files (.pcd, .graph, .ply, .xyz, CARMEN .log/.clf, OctoMap .dat)");
      files_.insert(files_.end(), found.begin(), found.end());
    } else if (std::filesystem::is_regular_file(status)) {
      scan_file_type(input);
      files_.push_back(input);
    } else if (std::filesystem::exists(status)) {
      throw InputError(input, "not a regular file or folder");
    } else {
      throw InputError(input, "no such file or folder");
    }
  }
  const bool all_bags = std::all_of(files_.begin(), files_.end(), [](const std::filesystem::path& f) {
    return scan_file_type(f) == ScanFileType::kRosbag;
  });
  const bool any_bag = std::any_of(files_.begin(), files_.end(), [](const std::filesystem::path& f) {
    return scan_file_type(f) == ScanFileType::kRosbag;
  });
  if (!any_bag && (!options_.topics.empty() || !options_.tf_frame.empty()))
    throw std::invalid_argument("--topic and --tf-frame are for ROS bag inputs (.bag), and none is given");
  const bool bags_by_poses = any_bag && options_.tf_frame.empty();
  if (bags_by_poses) check_bag_poses(all_bags);
  if (options_.poses.empty() && !options_.origin)
    for (const std::filesystem::path& file : files_)
      if (own_pose_field(scan_file_type(file))[0] == '\0')
        throw InputError(file, "PLY and XYZ files carry no sensor origin: give --origin X,Y,Z or --poses FILE");
  // Bags posed by --poses take its lines themselves, one a message (check_bag_poses).
  pose_rule_.emplace(bags_by_poses ? std::filesystem::path() : options_.poses, options_.origin, options_.frame, files_,
                     [this](size_t i) { return own_pose_of(files_[i], scan_file_type(files_[i]), options_); });
  if (!options_.pose_covariance.empty()) {
    if (pose_rule_->poses_carry_covariances() ||
        std::any_of(bag_poses_.begin(), bag_poses_.end(), [](const PoseRecord& r) { return r.covariance.has_value(); }))
      throw InputError(options_.poses, "covariances here and a pose covariance file too; give them once");
    covariances_ = read_pose_list(options_.pose_covariance);
    for (const PoseRecord& r : covariances_)
      if (!r.covariance)
        throw InputError(options_.pose_covariance,
                         "line " + std::to_string(r.line) + ": no covariance (a pose covariance file needs one a line)");
  }
  for (const std::filesystem::path& file : files_) {
    std::error_code ec;
    const ScanFileType type = scan_file_type(file);
    const uintmax_t bytes = type == ScanFileType::kKittiSequence ? 0 : std::filesystem::file_size(file, ec);
    file_bytes_.push_back(ec ? 0 : static_cast<uint64_t>(bytes));
    expected_scans_.push_back(holds_one_scan(type)                       ? 1
                              : type == ScanFileType::kKittiSequence ? kitti_scan_files(file, ec).size()
                                                                     : 0);
  }
  file_scans_.assign(files_.size(), 0);
}

uint64_t ScanSource::open_stream_size() const {
  return graph_ ? graph_->node_count() : kitti_ ? kitti_->size() : rosbag_ ? rosbag_->size() : 0;
}

double ScanSource::open_stream_fraction_read() const {
  return carmen_ ? carmen_->fraction_read() : octomap_log_ ? octomap_log_->fraction_read() : 0.0;
}

ScanProgress ScanSource::progress() const {
  ScanProgress p;
  uint64_t rate_scans = 0, rate_bytes = 0;  // of the files of many scans opened so far (not KITTI folders)
  const auto add_rate = [&](size_t file, uint64_t scans, uint64_t bytes) {
    if (expected_scans_[file] != 1 && file_bytes_[file] > 0) rate_scans += scans, rate_bytes += bytes;
  };
  for (size_t i = 0; i < next_file_; ++i) {
    const bool open = streaming() && i == stream_file_;
    const uint64_t scans = open ? stream_scan_ : file_scans_[i];
    p.done += scans;
    if (!open) {
      p.total += scans;
      add_rate(i, scans, file_bytes_[i]);
    } else if (const uint64_t size = open_stream_size(); size > 0) {
      p.total += std::max(size, scans);
      add_rate(i, size, file_bytes_[i]);
    } else {  // a log: its scans so far scaled by the share of it read
      const double fraction = open_stream_fraction_read();
      add_rate(i, scans, static_cast<uint64_t>(fraction * double(file_bytes_[i])));
      p.total += fraction > 0 ? std::max(scans, static_cast<uint64_t>(std::llround(double(scans) / fraction))) : scans;
      p.estimated = true;
    }
  }
  for (size_t i = next_file_; i < files_.size(); ++i) {
    if (expected_scans_[i] > 0) {
      p.total += expected_scans_[i];
      continue;
    }
    const double per_byte = rate_bytes > 0 ? double(rate_scans) / double(rate_bytes) : 0;
    p.total += std::max<uint64_t>(1, static_cast<uint64_t>(per_byte * double(file_bytes_[i])));
    p.estimated = true;
  }
  return p;
}

bool ScanSource::carries_pose_covariances() const {
  return !covariances_.empty() || pose_rule_->poses_carry_covariances() ||
         std::any_of(bag_poses_.begin(), bag_poses_.end(), [](const PoseRecord& r) { return r.covariance.has_value(); });
}

// Bags without --tf-frame: --poses gives each message its pose, one line a message, when every
// input is a bag (the pose rule's lines are one a file).
void ScanSource::check_bag_poses(bool all_bags) {
  const auto bag = std::find_if(files_.begin(), files_.end(),
                                [](const std::filesystem::path& f) { return scan_file_type(f) == ScanFileType::kRosbag; });
  if (options_.poses.empty())
    throw InputError(*bag, "a ROS bag's messages need poses: give --tf-frame FRAME (the fixed frame of its /tf) or "
                           "--poses FILE (one line a message)");
  if (!all_bags)
    throw InputError(options_.poses, "gives other inputs one pose a file, but a ROS bag one a message: give the bags "
                                     "alone with --poses, or --tf-frame");
  if (options_.origin) throw InputError(*bag, "--origin is not for ROS bags: give --tf-frame or --poses");
  bag_poses_ = read_pose_list(options_.poses);
  uint64_t messages = 0;
  for (const std::filesystem::path& file : files_) messages += RosbagReader::count_messages(file, options_.topics);
  if (bag_poses_.size() != messages)
    throw InputError(options_.poses, std::to_string(bag_poses_.size()) + " poses for " + std::to_string(messages) +
                                         " messages of the bags' --topic (one pose a message, in bag time order)");
}

void ScanSource::attach_covariance(Scan& scan) {
  const uint64_t index = scans_seen_++;
  if (options_.pose_covariance.empty()) return;
  const std::string name = "scan " + std::to_string(index + 1) + " (" + scan.source + ")";
  if (index >= covariances_.size())
    throw InputError(options_.pose_covariance,
                     std::to_string(covariances_.size()) + " lines, but the inputs hold at least " + name);
  const PoseRecord& r = covariances_[index];
  const double dx = double(r.pose.position.x) - scan.pose.position.x, dy = double(r.pose.position.y) - scan.pose.position.y,
               dz = double(r.pose.position.z) - scan.pose.position.z;
  if (!(std::sqrt(dx * dx + dy * dy + dz * dz) <= 1e-3)) {
    char where[512];
    std::snprintf(where, sizeof where, "(%.6g, %.6g, %.6g) is not the origin of %s, (%.6g, %.6g, %.6g)",
                  r.pose.position.x, r.pose.position.y, r.pose.position.z, name.c_str(), scan.pose.position.x,
                  scan.pose.position.y, scan.pose.position.z);
    throw InputError(options_.pose_covariance, "line " + std::to_string(r.line) + ": " + where);
  }
  scan.pose_covariance = r.covariance;
  scan.pose_covariance_source = options_.pose_covariance.string() + " line " + std::to_string(r.line);
}

// How many scans the rest of a failed file of many scans held is unknown, so which covariance line
// the next file's first scan takes is too: that ends the run even when bad inputs are skipped.
InputError ScanSource::covariance_lines_lost(const std::exception& e) const {
  return InputError(options_.pose_covariance, "cannot tell which lines belong to the scans after " +
                                                  std::to_string(stream_scan_) + " of " +
                                                  files_[stream_file_].string() + ", which failed: " + e.what());
}

bool ScanSource::next(Scan& scan) {
  const auto close_streams = [this] {
    if (streaming()) file_scans_[stream_file_] = stream_scan_;
    graph_.reset();
    carmen_.reset();
    octomap_log_.reset();
    kitti_.reset();
    rosbag_.reset();
  };
  for (;;) {
    if (graph_ || carmen_ || octomap_log_ || kitti_ || rosbag_) {
      bool more = false;
      try {
        more = graph_         ? graph_->next(scan)
               : carmen_      ? carmen_->next(scan)
               : octomap_log_ ? octomap_log_->next(scan)
               : rosbag_      ? rosbag_->next(scan)
                              : kitti_->next(scan);
      } catch (const RosbagMessageError&) {
        // One message of the bag, passed over as a whole scan (with its covariance line); the bag
        // goes on. A resumed map's held message is passed over quietly, as it was before.
        ++scans_seen_;
        if (stream_scan_++ < held(stream_file_)) continue;
        throw;
      } catch (const std::exception& e) {
        close_streams();  // the next call goes on with the next file
        if (!options_.pose_covariance.empty()) throw covariance_lines_lost(e);
        throw;
      }
      if (more) {
        const uint64_t index = stream_scan_++;
        if (index < held(stream_file_)) {
          ++scans_seen_;
          continue;
        }
        if (!rosbag_ || !options_.tf_frame.empty())  // a bag posed by --poses has its lines already
          pose_rule_->apply(scan, stream_file_, own_pose_field(scan_file_type(files_[stream_file_])));
        attach_covariance(scan);
        last_file_ = stream_file_;
        last_scan_ = index;
        return true;
      }
      if (carmen_)
        for (const auto& [type, count] : carmen_->skipped_messages()) skipped_[type] += count;
      close_streams();
    }
    if (next_file_ >= files_.size()) {
      if (!options_.pose_covariance.empty() && scans_seen_ != covariances_.size())
        throw InputError(options_.pose_covariance, std::to_string(covariances_.size()) + " lines for " +
                                                       std::to_string(scans_seen_) + " scans (one a scan, in input order)");
      return false;
    }
    const size_t index = next_file_++;
    const std::filesystem::path& file = files_[index];
    const ScanFileType type = scan_file_type(file);
    switch (type) {
      case ScanFileType::kPcd:
      case ScanFileType::kPly:
      case ScanFileType::kXyz:
        file_scans_[index] = 1;
        if (held(index) > 0) {
          ++scans_seen_;
          continue;
        }
        read_counting_failures(scans_seen_, [&] {
          scan = type == ScanFileType::kPcd ? read_pcd(file) : type == ScanFileType::kPly ? read_ply(file) : read_xyz(file);
          pose_rule_->apply(scan, index, own_pose_field(type));
        });
        attach_covariance(scan);
        last_file_ = index;
        last_scan_ = 0;
        return true;
      case ScanFileType::kGraph:
      case ScanFileType::kCarmenLog:
      case ScanFileType::kOctomapLog:
      case ScanFileType::kKittiSequence:
      case ScanFileType::kRosbag:
        break;
    }
    stream_file_ = index;
    stream_scan_ = 0;
    try {  // a file of many scans, read one scan at a time above
      if (type == ScanFileType::kGraph) graph_.emplace(file);
      else if (type == ScanFileType::kCarmenLog) carmen_.emplace(file);
      else if (type == ScanFileType::kOctomapLog) octomap_log_.emplace(file);
      else if (type == ScanFileType::kRosbag) {
        const uint64_t count = options_.tf_frame.empty() ? RosbagReader::count_messages(file, options_.topics) : 0;
        const size_t first = next_bag_pose_;
        next_bag_pose_ += count;  // this bag's lines, also when it cannot be read
        rosbag_.emplace(file, options_.topics, bag_pose_source(options_, bag_poses_, first, count));
        for (const auto& [message_type, n] : rosbag_->skipped_messages()) skipped_[message_type] += n;
      } else kitti_.emplace(file, options_.kitti_frame);
    } catch (const std::exception& e) {
      close_streams();
      if (!options_.pose_covariance.empty()) throw covariance_lines_lost(e);
      throw;
    }
  }
}

}  // namespace bgkmap
