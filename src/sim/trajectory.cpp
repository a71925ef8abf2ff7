#include "bgkmap/sim/trajectory.hpp"

#include <cmath>
#include <stdexcept>

namespace bgkmap::sim {

namespace {
constexpr double kDeg = M_PI / 180.0;

bool all_have_yaw(const std::vector<Waypoint>& w) {
  for (const auto& p : w)
    if (!p.yaw_deg) return false;
  return true;
}

double heading_deg(const Vec3d& from, const Vec3d& to, double fallback) {
  const double dx = to.x - from.x, dy = to.y - from.y;
  if (dx == 0 && dy == 0) return fallback;  // vertical or zero-length segment: keep the last heading
  return std::atan2(dy, dx) / kDeg;
}

// Interpolates angles the short way round.
double lerp_angle_deg(double a, double b, double f) {
  const double diff = std::remainder(b - a, 360.0);
  return a + f * diff;
}
}  // namespace

Pose pose_from_yaw(const Vec3d& position, double yaw_deg) {
  Pose pose;
  pose.position = {static_cast<float>(position.x), static_cast<float>(position.y), static_cast<float>(position.z)};
  const double half = 0.5 * std::remainder(yaw_deg, 360.0) * kDeg;  // qw >= 0: one quaternion per yaw
  pose.qw = static_cast<float>(std::cos(half));
  pose.qz = static_cast<float>(std::sin(half));
  return pose;
}

void Trajectory::validate() const {
  if (waypoints.empty()) throw std::invalid_argument("trajectory: no waypoints");
  if (scans < 1) throw std::invalid_argument("trajectory: scans must be at least 1");
  bool any_yaw = false;
  for (const auto& w : waypoints) {
    if (!std::isfinite(w.position.x) || !std::isfinite(w.position.y) || !std::isfinite(w.position.z))
      throw std::invalid_argument("trajectory: non-finite waypoint");
    if (w.yaw_deg && !std::isfinite(*w.yaw_deg)) throw std::invalid_argument("trajectory: non-finite yaw_deg");
    any_yaw = any_yaw || w.yaw_deg.has_value();
  }
  if (any_yaw && !all_have_yaw(waypoints))
    throw std::invalid_argument("trajectory: give yaw_deg on every waypoint or on none");
  if (waypoints.size() > 1 && scans > 1) {
    double length = 0;
    for (size_t i = 0; i + 1 < waypoints.size(); ++i) length += norm(waypoints[i + 1].position - waypoints[i].position);
    if (closed) length += norm(waypoints.front().position - waypoints.back().position);
    if (!(length > 0)) throw std::invalid_argument("trajectory: the waypoints are all at one place (use station)");
  }
}

std::vector<Pose> sample_poses(const Trajectory& trajectory) {
  trajectory.validate();
  const auto& w = trajectory.waypoints;
  const bool given_yaw = all_have_yaw(w);
  if (w.size() == 1) return std::vector<Pose>(trajectory.scans, pose_from_yaw(w[0].position, w[0].yaw_deg.value_or(0)));

  // Segments of the polyline (closing one included), their lengths and travel headings.
  std::vector<Vec3d> from, to;
  std::vector<double> yaw_from, yaw_to;
  const size_t segments = trajectory.closed ? w.size() : w.size() - 1;
  double heading = heading_deg(w[0].position, w[1].position, 0);
  for (size_t s = 0; s < segments; ++s) {
    const Waypoint& a = w[s];
    const Waypoint& b = w[(s + 1) % w.size()];
    from.push_back(a.position);
    to.push_back(b.position);
    heading = heading_deg(a.position, b.position, heading);
    yaw_from.push_back(given_yaw ? *a.yaw_deg : heading);
    yaw_to.push_back(given_yaw ? *b.yaw_deg : heading);
  }
  std::vector<double> start(segments + 1, 0.0);
  for (size_t s = 0; s < segments; ++s) start[s + 1] = start[s] + norm(to[s] - from[s]);
  const double length = start[segments];

  std::vector<Pose> poses;
  poses.reserve(trajectory.scans);
  const int n = trajectory.scans;
  const double spacing = n == 1 ? 0.0 : length / (trajectory.closed ? n : n - 1);
  size_t s = 0;
  for (int k = 0; k < n; ++k) {
    const double d = std::fmin(k * spacing, length);
    while (s + 1 < segments && start[s + 1] <= d && start[s + 1] < length) ++s;
    const double seg_length = start[s + 1] - start[s];
    const double f = seg_length > 0 ? (d - start[s]) / seg_length : 0.0;
    const Vec3d p = from[s] + f * (to[s] - from[s]);
    poses.push_back(pose_from_yaw(p, lerp_angle_deg(yaw_from[s], yaw_to[s], f)));
  }
  return poses;
}

}  // namespace bgkmap::sim
