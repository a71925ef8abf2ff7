#include "bgkmap/core/pose_covariance.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace bgkmap {

PoseSigma parse_pose_sigma(const std::string& text) {
  std::vector<double> values;
  size_t start = 0;
  for (;;) {
    const size_t comma = text.find(',', start);
    const std::string field = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    size_t used = 0;
    double v = 0;
    try {
      v = std::stod(field, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (field.empty() || used != field.size())
      throw std::invalid_argument("pose sigma '" + text + "': '" + field + "' is not a number");
    if (!std::isfinite(v) || v < 0)
      throw std::invalid_argument("pose sigma '" + text + "': each value must be finite and >= 0");
    values.push_back(v);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  if (values.size() != 2 && values.size() != 4)
    throw std::invalid_argument("pose sigma '" + text + "': expected XY,YAW or XY,YAW,Z,ROLLPITCH (m, rad)");
  PoseSigma s;
  s.xy_m = values[0];
  s.yaw_rad = values[1];
  if (values.size() == 4) {
    s.z_m = values[2];
    s.roll_pitch_rad = values[3];
  }
  return s;
}

std::string to_string(const PoseSigma& s) {
  char text[128];
  if (s.z_m == 0 && s.roll_pitch_rad == 0) std::snprintf(text, sizeof text, "%.17g,%.17g", s.xy_m, s.yaw_rad);
  else std::snprintf(text, sizeof text, "%.17g,%.17g,%.17g,%.17g", s.xy_m, s.yaw_rad, s.z_m, s.roll_pitch_rad);
  return text;
}

bool PoseCovariance::is_zero() const {
  return std::all_of(m.begin(), m.end(), [](double v) { return v == 0; });
}

PoseCovariance PoseCovariance::from_sigma(const PoseSigma& s) {
  PoseCovariance c;
  const double diag[6] = {s.xy_m, s.xy_m, s.z_m, s.roll_pitch_rad, s.roll_pitch_rad, s.yaw_rad};
  for (int i = 0; i < 6; ++i) c(i, i) = diag[i] * diag[i];
  return c;
}

PoseCovariance PoseCovariance::from_planar(const std::array<double, 9>& xy_yaw) {
  static const int axis[3] = {0, 1, 5};  // x, y, yaw in the 6x6
  PoseCovariance c;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) c(axis[i], axis[j]) = xy_yaw[static_cast<size_t>(3 * i + j)];
  return c;
}

namespace {
// Pivoted outer-product Cholesky: columns s_k with sum_k s_k s_k^T = c. Stops at the first pivot
// below `floor`; a pivot below -floor means c is not positive semi-definite (returns false).
bool pivoted_cholesky(const PoseCovariance& c, std::vector<std::array<double, 6>>& columns) {
  PoseCovariance a = c;
  double largest = 0;
  for (int i = 0; i < 6; ++i) largest = std::max(largest, std::abs(c(i, i)));
  const double floor = 1e-12 * largest;
  columns.clear();
  bool used[6] = {};
  for (int k = 0; k < 6; ++k) {
    int p = -1;
    for (int i = 0; i < 6; ++i)
      if (!used[i] && (p < 0 || a(i, i) > a(p, p))) p = i;
    if (a(p, p) < -floor) return false;
    if (!(a(p, p) > floor)) break;
    // The rest of the matrix must be semi-definite: a negative diagonal left behind fails later.
    used[p] = true;
    std::array<double, 6> s{};
    const double root = std::sqrt(a(p, p));
    for (int i = 0; i < 6; ++i) s[static_cast<size_t>(i)] = used[i] && i != p ? 0.0 : a(i, p) / root;
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j < 6; ++j) a(i, j) -= s[static_cast<size_t>(i)] * s[static_cast<size_t>(j)];
    columns.push_back(s);
  }
  for (int i = 0; i < 6; ++i)
    if (a(i, i) < -floor) return false;
  // What is left must be (numerically) zero, off the diagonal too.
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j)
      if (std::abs(a(i, j)) > 1e-6 * std::max(largest, 1e-300)) return false;
  return true;
}
}  // namespace

std::string pose_covariance_problem(const PoseCovariance& c) {
  double largest = 0;
  for (double v : c.m) {
    if (!std::isfinite(v)) return "not finite";
    largest = std::max(largest, std::abs(v));
  }
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < i; ++j)
      if (std::abs(c(i, j) - c(j, i)) > 1e-9 * largest) return "not symmetric";
  std::vector<std::array<double, 6>> columns;
  if (!pivoted_cholesky(c, columns)) return "not positive semi-definite";
  return {};
}

std::vector<PoseSigmaPoint> pose_sigma_points(const PoseCovariance& c) {
  std::vector<std::array<double, 6>> columns;
  if (!pivoted_cholesky(c, columns)) throw std::invalid_argument("pose covariance is not positive semi-definite");
  const size_t n = columns.size();
  std::vector<PoseSigmaPoint> points;
  if (n == 0) return points;
  const double spread = std::sqrt(static_cast<double>(n)), weight = 1.0 / (2.0 * static_cast<double>(n));
  for (const std::array<double, 6>& s : columns)
    for (const double sign : {1.0, -1.0}) {
      const double f = sign * spread;
      PoseSigmaPoint p;
      p.weight = weight;
      p.translation = {f * s[0], f * s[1], f * s[2]};
      p.rotation = {f * s[3], f * s[4], f * s[5]};
      points.push_back(p);
    }
  return points;
}

std::array<double, 9> rotation_matrix(const Vec3d& r) {
  const double theta = std::sqrt(r.x * r.x + r.y * r.y + r.z * r.z);
  // sin(t)/t and (1 - cos(t))/t^2, by their series near 0.
  const double t2 = theta * theta;
  const double a = theta < 1e-4 ? 1 - t2 / 6 : std::sin(theta) / theta;
  const double b = theta < 1e-4 ? 0.5 - t2 / 24 : (1 - std::cos(theta)) / t2;
  const double x = r.x, y = r.y, z = r.z;
  return {1 - b * (y * y + z * z), -a * z + b * x * y, a * y + b * x * z,
          a * z + b * x * y, 1 - b * (x * x + z * z), -a * x + b * y * z,
          -a * y + b * x * z, a * x + b * y * z, 1 - b * (x * x + y * y)};
}

}  // namespace bgkmap
