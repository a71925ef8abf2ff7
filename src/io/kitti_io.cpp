#include "bgkmap/io/kitti_io.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <string>

#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "input_file.hpp"
#include "text_lines.hpp"

namespace bgkmap {

namespace {
using io_detail::parse_number;
using io_detail::split_fields;
using io_detail::TextLines;
using Matrix34 = std::array<double, 12>;

Matrix34 parse_matrix(const TextLines& lines, const std::vector<std::string_view>& f, size_t first, const char* what) {
  if (f.size() != first + 12)
    lines.fail(std::string(what) + ": " + std::to_string(f.size() - first) + " numbers, expected 12 (a 3x4 matrix)");
  Matrix34 m;
  for (size_t i = 0; i < 12; ++i)
    if (!parse_number(f[first + i], m[i]) || !std::isfinite(m[i]))
      lines.fail(std::string(what) + ": value " + std::to_string(i + 1) + " is not a finite number");
  return m;
}

// a * b for 3x4 rigid transforms (the implicit last row 0 0 0 1).
Matrix34 compose(const Matrix34& a, const Matrix34& b) {
  Matrix34 c;
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 4; ++k) {
      double v = k == 3 ? a[r * 4 + 3] : 0.0;
      for (int j = 0; j < 3; ++j) v += a[r * 4 + j] * b[j * 4 + k];
      c[r * 4 + k] = v;
    }
  }
  return c;
}

// The inverse of a rigid 3x4 transform [R | t]: [R^T | -R^T t].
Matrix34 rigid_inverse(const Matrix34& m) {
  Matrix34 inv;
  for (int r = 0; r < 3; ++r) {
    double t = 0;
    for (int j = 0; j < 3; ++j) {
      inv[r * 4 + j] = m[j * 4 + r];
      t -= m[j * 4 + r] * m[j * 4 + 3];
    }
    inv[r * 4 + 3] = t;
  }
  return inv;
}

// The rotation part as a unit quaternion (Shepperd's method).
void set_orientation(const Matrix34& m, Pose& pose) {
  const double r00 = m[0], r01 = m[1], r02 = m[2], r10 = m[4], r11 = m[5], r12 = m[6], r20 = m[8], r21 = m[9], r22 = m[10];
  const double trace = r00 + r11 + r22;
  double w, x, y, z;
  if (trace > 0) {
    const double s = 2 * std::sqrt(1 + trace);
    w = s / 4, x = (r21 - r12) / s, y = (r02 - r20) / s, z = (r10 - r01) / s;
  } else if (r00 > r11 && r00 > r22) {
    const double s = 2 * std::sqrt(std::max(1e-12, 1 + r00 - r11 - r22));
    w = (r21 - r12) / s, x = s / 4, y = (r01 + r10) / s, z = (r02 + r20) / s;
  } else if (r11 > r22) {
    const double s = 2 * std::sqrt(std::max(1e-12, 1 + r11 - r00 - r22));
    w = (r02 - r20) / s, x = (r01 + r10) / s, y = s / 4, z = (r12 + r21) / s;
  } else {
    const double s = 2 * std::sqrt(std::max(1e-12, 1 + r22 - r00 - r11));
    w = (r10 - r01) / s, x = (r02 + r20) / s, y = (r12 + r21) / s, z = s / 4;
  }
  const double n = std::sqrt(w * w + x * x + y * y + z * z);
  pose.qw = static_cast<float>(w / n), pose.qx = static_cast<float>(x / n);
  pose.qy = static_cast<float>(y / n), pose.qz = static_cast<float>(z / n);
}

std::filesystem::path require_file(const std::filesystem::path& folder, const char* name) {
  const std::filesystem::path file = folder / name;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) throw InputError(file, "missing: a KITTI sequence folder needs velodyne/, poses.txt and calib.txt");
  return file;
}
}  // namespace

bool is_kitti_sequence(const std::filesystem::path& folder) {
  std::error_code ec;
  return std::filesystem::is_directory(folder / "velodyne", ec) && std::filesystem::exists(folder / "calib.txt", ec);
}

std::vector<std::filesystem::path> kitti_scan_files(const std::filesystem::path& folder, std::error_code& ec) {
  std::vector<std::filesystem::path> scans;
  for (std::filesystem::directory_iterator it(folder / "velodyne", ec), end; !ec && it != end; it.increment(ec))
    if (it->path().extension() == ".bin") scans.push_back(it->path());
  std::sort(scans.begin(), scans.end(), [](const std::filesystem::path& a, const std::filesystem::path& b) {
    return natural_less(a.filename().string(), b.filename().string());
  });
  return scans;
}

KittiSequenceReader::KittiSequenceReader(const std::filesystem::path& folder, KittiFrame frame) {
  std::optional<Matrix34> tr;
  {
    TextLines lines(require_file(folder, "calib.txt"));
    std::string line;
    while (lines.next(line)) {
      const auto f = split_fields(line);
      if (!f.empty() && f[0] == "Tr:") tr = parse_matrix(lines, f, 1, "calib Tr");
    }
    if (!tr) throw InputError(lines.file(), "no 'Tr:' line (velodyne to camera 0)");
  }
  std::vector<Matrix34> poses;
  const std::filesystem::path poses_file = require_file(folder, "poses.txt");
  {
    TextLines lines(poses_file);
    std::string line;
    while (lines.next(line)) {
      const auto f = split_fields(line);
      if (f.empty()) continue;
      poses.push_back(parse_matrix(lines, f, 0, "pose"));
    }
  }
  std::error_code ec;
  const std::filesystem::path velodyne = folder / "velodyne";
  scans_ = kitti_scan_files(folder, ec);
  if (ec) throw InputError(velodyne, "cannot list folder (" + ec.message() + ")");
  if (poses.size() != scans_.size())
    throw InputError(poses_file, std::to_string(poses.size()) + " poses for " + std::to_string(scans_.size()) +
                                     " scans in " + velodyne.string() + " (one pose a scan)");
  for (const Matrix34& p : poses) velodyne_to_world_.push_back(compose(p, *tr));
  if (frame == KittiFrame::kVelodyne && !velodyne_to_world_.empty()) {
    const Matrix34 world_from_first = rigid_inverse(velodyne_to_world_.front());
    for (Matrix34& m : velodyne_to_world_) m = compose(world_from_first, m);
  }
}

bool KittiSequenceReader::next(Scan& scan) {
  if (next_ >= scans_.size()) return false;
  const std::filesystem::path& file = scans_[next_];
  const Matrix34& m = velodyne_to_world_[next_++];
  std::error_code ec;
  const uint64_t bytes = std::filesystem::file_size(file, ec);
  if (ec) throw InputError(file, "cannot read (" + ec.message() + ")");
  if (bytes % 16 != 0)
    throw InputError(file, "KITTI: " + std::to_string(bytes) + " bytes is not a whole number of points (16 bytes each: x y z reflectance)");
  io_detail::require_read_memory(file, bytes / 16, 16 + sizeof(Vec3f));  // the raw floats, then the points
  std::ifstream in(file, std::ios::binary);
  std::vector<float> raw(bytes / 4);
  if (!in.read(reinterpret_cast<char*>(raw.data()), static_cast<std::streamsize>(bytes)))
    throw InputError(file, "KITTI: read error");
  scan = Scan{};
  scan.source = file.string();
  scan.pose.position = {static_cast<float>(m[3]), static_cast<float>(m[7]), static_cast<float>(m[11])};
  set_orientation(m, scan.pose);
  scan.points_in_world_frame = true;
  scan.points.resize(bytes / 16);
  for (size_t i = 0; i < scan.points.size(); ++i) {
    const double x = raw[4 * i], y = raw[4 * i + 1], z = raw[4 * i + 2];
    scan.points[i] = {static_cast<float>(m[0] * x + m[1] * y + m[2] * z + m[3]),
                      static_cast<float>(m[4] * x + m[5] * y + m[6] * z + m[7]),
                      static_cast<float>(m[8] * x + m[9] * y + m[10] * z + m[11])};
  }
  return true;
}

}  // namespace bgkmap
