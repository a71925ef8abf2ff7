#include "bgkmap/io/scan_source.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>

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
         is_carmen_log_name(file);
}

// The field that gives a file of this type its pose, for messages and the report's counts.
const char* own_pose_field(ScanFileType type) {
  switch (type) {
    case ScanFileType::kPcd: return "PCD VIEWPOINT";
    case ScanFileType::kGraph: return ".graph nodes";
    case ScanFileType::kCarmenLog: return "CARMEN laser lines";
    case ScanFileType::kOctomapLog: return "OctoMap log NODE lines";
    case ScanFileType::kKittiSequence: return "KITTI poses.txt";
    case ScanFileType::kPly:
    case ScanFileType::kXyz: break;
  }
  return "";
}

// What gives `file` a pose of its own, or "" when it has none (a PCD by its header).
std::string own_pose_of(const std::filesystem::path& file, ScanFileType type) {
  if (type == ScanFileType::kPcd) return pcd_has_viewpoint(file) ? "a VIEWPOINT" : "";
  return own_pose_field(type);
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
  if (is_carmen_log_name(file)) return looks_like_octomap_log(file) ? ScanFileType::kOctomapLog : ScanFileType::kCarmenLog;
  const std::string hint = ext == ".bt" || ext == ".ot" ? " (an OctoMap map, not a scan)" : "";
  throw InputError(file, "unsupported scan file type '" + ext + "'" + hint +
                             "; expected .pcd, .graph, .ply, .xyz, a CARMEN log (.log, .clf), an OctoMap log (.dat) "
                             "or a KITTI sequence folder");
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
  if (options_.poses.empty() && !options_.origin)
    for (const std::filesystem::path& file : files_)
      if (own_pose_field(scan_file_type(file))[0] == '\0')
        throw InputError(file, "PLY and XYZ files carry no sensor origin: give --origin X,Y,Z or --poses FILE");
  pose_rule_.emplace(options_.poses, options_.origin, options_.frame, files_,
                     [this](size_t i) { return own_pose_of(files_[i], scan_file_type(files_[i])); });
  if (!options_.pose_covariance.empty()) {
    if (pose_rule_->poses_carry_covariances())
      throw InputError(options_.poses, "covariances here and a pose covariance file too; give them once");
    covariances_ = read_pose_list(options_.pose_covariance);
    for (const PoseRecord& r : covariances_)
      if (!r.covariance)
        throw InputError(options_.pose_covariance,
                         "line " + std::to_string(r.line) + ": no covariance (a pose covariance file needs one a line)");
  }
}

bool ScanSource::carries_pose_covariances() const {
  return !covariances_.empty() || pose_rule_->poses_carry_covariances();
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
    graph_.reset();
    carmen_.reset();
    octomap_log_.reset();
    kitti_.reset();
  };
  for (;;) {
    if (graph_ || carmen_ || octomap_log_ || kitti_) {
      bool more = false;
      try {
        more = graph_         ? graph_->next(scan)
               : carmen_      ? carmen_->next(scan)
               : octomap_log_ ? octomap_log_->next(scan)
                              : kitti_->next(scan);
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
        break;
    }
    stream_file_ = index;
    stream_scan_ = 0;
    try {  // a file of many scans, read one scan at a time above
      if (type == ScanFileType::kGraph) graph_.emplace(file);
      else if (type == ScanFileType::kCarmenLog) carmen_.emplace(file);
      else if (type == ScanFileType::kOctomapLog) octomap_log_.emplace(file);
      else kitti_.emplace(file, options_.kitti_frame);
    } catch (const std::exception& e) {
      close_streams();
      if (!options_.pose_covariance.empty()) throw covariance_lines_lost(e);
      throw;
    }
  }
}

}  // namespace bgkmap
