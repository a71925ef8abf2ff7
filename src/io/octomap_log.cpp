#include "bgkmap/io/octomap_log.hpp"

#include <cmath>
#include <optional>
#include <string>

#include "bgkmap/io/errors.hpp"
#include "text_lines.hpp"

namespace bgkmap {

namespace {
using io_detail::parse_number;
using io_detail::split_fields;
using io_detail::TextLines;

bool skipped(const std::vector<std::string_view>& f) { return f.empty() || f[0].front() == '#'; }

// OctoMap's octomath::Quaternion(roll, pitch, yaw): q = q_z(yaw) q_y(pitch) q_x(roll).
Pose pose_from_rpy(double x, double y, double z, double roll, double pitch, double yaw) {
  const double cr = std::cos(roll / 2), sr = std::sin(roll / 2);
  const double cp = std::cos(pitch / 2), sp = std::sin(pitch / 2);
  const double cy = std::cos(yaw / 2), sy = std::sin(yaw / 2);
  Pose p;
  p.position = {static_cast<float>(x), static_cast<float>(y), static_cast<float>(z)};
  p.qw = static_cast<float>(cr * cp * cy + sr * sp * sy);
  p.qx = static_cast<float>(sr * cp * cy - cr * sp * sy);
  p.qy = static_cast<float>(cr * sp * cy + sr * cp * sy);
  p.qz = static_cast<float>(cr * cp * sy - sr * sp * cy);
  return p;
}
}  // namespace

bool looks_like_octomap_log(const std::filesystem::path& file) {
  try {
    TextLines lines(file);
    std::string line;
    for (int n = 0; n < 1000 && lines.next(line); ++n) {
      const auto f = split_fields(line);
      if (skipped(f)) continue;
      return f[0] == "NODE";
    }
  } catch (const InputError&) {
  }
  return false;
}

struct OctomapLogReader::State {
  explicit State(const std::filesystem::path& file) : lines(file) {}
  TextLines lines;
  std::string line;
  std::optional<Pose> pending;  // the NODE read ahead: the pose of the next scan
  bool started = false;

  Pose parse_node(const std::vector<std::string_view>& f) const {
    if (f.size() != 7) lines.fail("NODE: " + std::to_string(f.size() - 1) + " values, expected x y z roll pitch yaw");
    double v[6];
    for (int i = 0; i < 6; ++i)
      if (!parse_number(f[i + 1], v[i]) || !std::isfinite(v[i]))
        lines.fail("NODE: value " + std::to_string(i + 1) + " is not a finite number");
    return pose_from_rpy(v[0], v[1], v[2], v[3], v[4], v[5]);
  }
};

OctomapLogReader::OctomapLogReader(const std::filesystem::path& file) : state_(std::make_unique<State>(file)) {}
OctomapLogReader::~OctomapLogReader() = default;
OctomapLogReader::OctomapLogReader(OctomapLogReader&&) noexcept = default;
OctomapLogReader& OctomapLogReader::operator=(OctomapLogReader&&) noexcept = default;

double OctomapLogReader::fraction_read() const { return state_->lines.fraction_read(); }

bool OctomapLogReader::next(Scan& scan) {
  State& s = *state_;
  if (!s.pending) {
    if (s.started) return false;
    while (s.lines.next(s.line)) {  // the first NODE
      const auto f = split_fields(s.line);
      if (skipped(f)) continue;
      if (f[0] != "NODE") s.lines.fail("points before the first NODE line");
      s.pending = s.parse_node(f);
      break;
    }
    s.started = true;
    if (!s.pending) return false;  // an empty log
  }
  scan = Scan{};
  scan.pose = *s.pending;
  scan.source = s.lines.file().string();
  scan.points_in_world_frame = true;
  s.pending.reset();
  while (s.lines.next(s.line)) {
    const auto f = split_fields(s.line);
    if (skipped(f)) continue;
    if (f[0] == "NODE") {
      s.pending = s.parse_node(f);
      break;
    }
    double v[3];
    if (f.size() != 3) s.lines.fail("point: " + std::to_string(f.size()) + " fields, expected x y z");
    for (int i = 0; i < 3; ++i)
      if (!parse_number(f[i], v[i])) s.lines.fail("point: field " + std::to_string(i + 1) + " is not a number");
    scan.points.push_back(scan.pose.transform({static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2])}));
  }
  return true;
}

}  // namespace bgkmap
