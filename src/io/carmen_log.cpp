#include "bgkmap/io/carmen_log.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <string_view>
#include <vector>

#include "bgkmap/io/errors.hpp"
#include "text_lines.hpp"

namespace bgkmap {

namespace {

using io_detail::parse_count;
using io_detail::parse_number;
using io_detail::TextLines;

constexpr double kPi = 3.14159265358979323846;
// Distinct skipped message types listed by name; more (a log of garbage) are counted together.
constexpr size_t kMaxSkippedTypes = 64;

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

bool ends_with(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

std::string quoted(std::string_view field) {
  constexpr size_t kShown = 24;
  return "'" + std::string(field.substr(0, kShown)) + (field.size() > kShown ? "...'" : "'");
}

}  // namespace

bool is_carmen_log_name(const std::filesystem::path& file) {
  std::string name = lower(file.filename().string());
  if (ends_with(name, ".gz")) name.resize(name.size() - 3);
  return ends_with(name, ".log") || ends_with(name, ".clf");
}

struct CarmenLogReader::State {
  explicit State(const std::filesystem::path& file) : lines(file) {}

  TextLines lines;
  std::string line;
  std::map<std::string, uint64_t> skipped;

  double number(const std::vector<std::string_view>& f, size_t i, const char* type, const std::string& what) const {
    double v;
    if (!parse_number(f[i], v)) lines.fail(std::string(type) + ": " + what + " " + quoted(f[i]) + " is not a number");
    return v;
  }

  double finite(const std::vector<std::string_view>& f, size_t i, const char* type, const std::string& what) const {
    const double v = number(f, i, type, what);
    if (!std::isfinite(v)) lines.fail(std::string(type) + ": " + what + " is not finite");
    return v;
  }

  // The count at field i, checked against the fields there are (so no absurd allocation).
  size_t count(const std::vector<std::string_view>& f, size_t i, const char* type, const char* what) const {
    uint64_t n = 0;
    if (i >= f.size() || !parse_count(f[i], f.size(), n))
      lines.fail(std::string(type) + ": the " + what + " " + (i < f.size() ? quoted(f[i]) : "(missing)") +
                 " is not a count that fits the line's " + std::to_string(f.size()) + " fields");
    return static_cast<size_t>(n);
  }

  // After `fixed` fields come "ipc_timestamp ipc_hostname [logger_timestamp]": numbers around a
  // name. Any other shape means the count disagrees with the data (or the line is cut short).
  void check_length(const std::vector<std::string_view>& f, size_t fixed, const char* type, const std::string& counts) const {
    const std::string disagree = " (the count disagrees with the data)";
    if (f.size() != fixed + 2 && f.size() != fixed + 3)
      lines.fail(std::string(type) + ": " + counts + " give " + std::to_string(fixed + 2) + " or " +
                 std::to_string(fixed + 3) + " fields, the line has " + std::to_string(f.size()) + disagree);
    double v;
    const bool shaped = parse_number(f[fixed], v) && !parse_number(f[fixed + 1], v) &&
                        (f.size() == fixed + 2 || parse_number(f[fixed + 2], v));
    if (!shaped)
      lines.fail(std::string(type) + ": " + counts + " leave " + quoted(f[fixed]) + " " + quoted(f[fixed + 1]) +
                 " where the timestamp and host name belong" + disagree);
  }

  void scan_from_readings(const std::vector<std::string_view>& f, size_t first, size_t n, double x, double y,
                          double theta, double start_angle, double step, float no_return, const char* type,
                          Scan& scan) const {
    scan.points.clear();
    scan.points.reserve(n);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (size_t i = 0; i < n; ++i) {
      const double r = number(f, first + i, type, "reading " + std::to_string(i + 1));
      if (!(r > 0) || !std::isfinite(r)) {  // no measurement: dropped and counted by preprocessing
        scan.points.push_back({nan, nan, nan});
        continue;
      }
      const double a = theta + start_angle + double(i) * step;
      scan.points.push_back({static_cast<float>(x + r * std::cos(a)), static_cast<float>(y + r * std::sin(a)), 0.0f});
    }
    scan.pose = Pose{};
    scan.pose.position = {static_cast<float>(x), static_cast<float>(y), 0.0f};
    scan.pose.qw = static_cast<float>(std::cos(0.5 * theta));
    scan.pose.qz = static_cast<float>(std::sin(0.5 * theta));
    scan.points_in_world_frame = true;
    scan.no_return_range_m = no_return;
    scan.source = lines.file().string();
  }

  // FLASER / RLASER n r_1 .. r_n x y theta odom_x odom_y odom_theta ipc_timestamp ipc_hostname [logger_timestamp]
  void parse_laser(const std::vector<std::string_view>& f, const char* type, Scan& scan) const {
    const size_t n = count(f, 1, type, "reading count");
    check_length(f, 2 + n + 6, type, std::to_string(n) + " readings");
    const size_t pose = 2 + n;
    const double x = finite(f, pose, type, "x"), y = finite(f, pose + 1, type, "y");
    const double theta = finite(f, pose + 2, type, "theta");
    const double step = n > 0 ? kPi / double(n) : 0.0;
    scan_from_readings(f, 2, n, x, y, theta, -0.5 * kPi, step, kCarmenNoReturnRangeM, type, scan);
  }

  // ROBOTLASER1 laser_type start_angle fov angular_res max_range accuracy remission_mode n r_1 .. r_n
  //   m v_1 .. v_m x y theta robot_x robot_y robot_theta tv rv forward_safety side_safety turn_axis
  //   ipc_timestamp ipc_hostname [logger_timestamp]
  void parse_robot_laser(const std::vector<std::string_view>& f, Scan& scan) const {
    const char* type = "ROBOTLASER1";
    const size_t n = count(f, 8, type, "reading count");
    const size_t m = count(f, 9 + n, type, "remission count");
    check_length(f, 10 + n + m + 11, type, std::to_string(n) + " readings and " + std::to_string(m) + " remissions");
    const double start_angle = finite(f, 2, type, "start angle");
    const double step = finite(f, 4, type, "angular resolution");
    const double max_range = number(f, 5, type, "maximum range");
    const size_t pose = 10 + n + m;
    const double x = finite(f, pose, type, "x"), y = finite(f, pose + 1, type, "y");
    const double theta = finite(f, pose + 2, type, "theta");
    const float no_return = max_range > 0 && std::isfinite(max_range) ? static_cast<float>(max_range) : 0.0f;
    scan_from_readings(f, 9, n, x, y, theta, start_angle, step, no_return, type, scan);
  }

  void count_skipped(std::string_view type) {
    std::string name(type.substr(0, 32));
    if (!skipped.count(name) && skipped.size() >= kMaxSkippedTypes) name = "(other)";
    ++skipped[name];
  }
};

CarmenLogReader::CarmenLogReader(const std::filesystem::path& file) : state_(std::make_unique<State>(file)) {}
CarmenLogReader::~CarmenLogReader() = default;
CarmenLogReader::CarmenLogReader(CarmenLogReader&&) noexcept = default;
CarmenLogReader& CarmenLogReader::operator=(CarmenLogReader&&) noexcept = default;

const std::map<std::string, uint64_t>& CarmenLogReader::skipped_messages() const { return state_->skipped; }

double CarmenLogReader::fraction_read() const { return state_->lines.fraction_read(); }

bool CarmenLogReader::next(Scan& scan) {
  State& s = *state_;
  while (s.lines.next(s.line)) {
    const std::vector<std::string_view> f = io_detail::split_fields(s.line);
    if (f.empty() || f[0].front() == '#') continue;
    if (f[0] == "FLASER" || f[0] == "RLASER") {
      s.parse_laser(f, f[0] == "FLASER" ? "FLASER" : "RLASER", scan);
      return true;
    }
    if (f[0] == "ROBOTLASER1") {
      s.parse_robot_laser(f, scan);
      return true;
    }
    s.count_skipped(f[0]);
  }
  return false;
}

}  // namespace bgkmap
