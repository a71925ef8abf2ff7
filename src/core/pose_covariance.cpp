#include "bgkmap/core/pose_covariance.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <utility>

#include "core/number_text.hpp"

namespace bgkmap {

PoseSigma parse_pose_sigma(const std::string& text, const std::string& name) {
  const auto refuse = [&](const std::string& why) { return std::invalid_argument(name + " '" + text + "': " + why); };
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
    if (field.empty() || used != field.size()) throw refuse("'" + field + "' is not a number");
    if (!std::isfinite(v) || v < 0) throw refuse("each value must be finite and >= 0");
    values.push_back(v);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  if (values.size() != 2 && values.size() != 4) throw refuse("expected XY,YAW or XY,YAW,Z,ROLLPITCH (m, rad)");
  PoseSigma s;
  s.xy_m = values[0];
  s.yaw_rad = values[1];
  if (values.size() == 4) {
    s.z_m = values[2];
    s.roll_pitch_rad = values[3];
  }
  const std::string problem = pose_sigma_problem(s);
  if (!problem.empty()) throw refuse(problem);
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

// Why a standard deviation `sd` of the axis `name` cannot be meant (kMaxPose*Sigma*), or empty.
std::string deviation_problem(const std::string& name, double sd, bool rotation) {
  if (!rotation && sd > kMaxPoseTranslationSigmaM)
    return "too large to be meant: " + name + "'s standard deviation " + number_text(sd) +
           " m is beyond the map's key range (at most " + number_text(kMaxPoseTranslationSigmaM) + " m)";
  if (rotation && sd > kMaxPoseRotationSigmaRad)
    return "too large to be meant: " + name + "'s standard deviation " + number_text(sd) +
           " rad is beyond pi (half a turn: no heading left to know)";
  return {};
}

const char* const kAxisNames[6] = {"x", "y", "z", "roll", "pitch", "yaw"};

// What any entry may be off by beside the relative tolerance: where a variance printed as 0 stands
// for a tiny one, sqrt(c_ii c_jj) is 0 and its covariances' own rounding (1e-20 next to 1e-2)
// would otherwise make c "not positive semi-definite".
double rounding_floor(const PoseCovariance& c) {
  double largest = 0;
  for (double v : c.m) largest = std::max(largest, std::abs(v));
  return 1e-12 * largest;
}

// Pivoted outer-product Cholesky of c's symmetric part: columns s_k with sum_k s_k s_k^T = c.
// Each step takes the axis with the largest remaining fraction of its own variance c_ii (ties:
// the largest remaining variance, so a diagonal c goes largest variance first); axes whose
// fraction is below kPoseCovarianceTolerance are explained by those taken, and one below minus
// it means c is not positive semi-definite (returns false). Fractions, not variances, so that
// metres and radians of any scale are judged alike, and a pivot explained nearly away (whose
// rounding the later steps would magnify) is taken last. c must be finite with entries within
// (1 + tolerance) sqrt(c_ii c_jj) (pose_covariance_problem checks first), which keeps every
// product finite.
bool pivoted_cholesky(const PoseCovariance& c, std::vector<std::array<double, 6>>& columns) {
  constexpr double tol = kPoseCovarianceTolerance;
  const double floor = rounding_floor(c);
  PoseCovariance a;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j) a(i, j) = 0.5 * (c(i, j) + c(j, i));
  columns.clear();
  bool used[6] = {};
  for (int k = 0; k < 6; ++k) {
    int p = -1;
    double best = 0;
    for (int i = 0; i < 6; ++i) {
      if (used[i]) continue;
      if (a(i, i) < -tol * c(i, i) - floor) return false;
      if (!(a(i, i) > tol * c(i, i))) continue;
      const double fraction = a(i, i) / c(i, i);
      if (p < 0 || fraction > best || (fraction == best && a(i, i) > a(p, p))) p = i, best = fraction;
    }
    if (p < 0) break;
    used[p] = true;
    std::array<double, 6> s{};
    const double root = std::sqrt(a(p, p));
    for (int i = 0; i < 6; ++i) s[static_cast<size_t>(i)] = used[i] && i != p ? 0.0 : a(i, p) / root;
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j < 6; ++j) a(i, j) -= s[static_cast<size_t>(i)] * s[static_cast<size_t>(j)];
    columns.push_back(s);
  }
  // What is left is zero within the tolerance, off the diagonal too, as a semi-definite rest with
  // such a diagonal must be (|a_ij| <= sqrt(a_ii a_jj)).
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j)
      if (!used[i] && !used[j] && i != j &&
          std::abs(a(i, j)) > tol * std::sqrt(c(i, i)) * std::sqrt(c(j, j)) + floor)
        return false;
  return true;
}
}  // namespace

std::string pose_covariance_problem(const PoseCovariance& c) {
  for (double v : c.m)
    if (!std::isfinite(v)) return "not finite";
  for (int i = 0; i < 6; ++i)
    if (c(i, i) < 0) return "not positive semi-definite";  // a negative variance
  for (int i = 0; i < 6; ++i) {
    const std::string problem = deviation_problem(kAxisNames[i], std::sqrt(c(i, i)), i >= 3);
    if (!problem.empty()) return problem;
  }
  constexpr double tol = kPoseCovarianceTolerance;
  const double floor = rounding_floor(c);
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < i; ++j)
      if (std::abs(c(i, j) - c(j, i)) > tol * std::sqrt(c(i, i)) * std::sqrt(c(j, j)) + floor) return "not symmetric";
  // A correlation beyond 1 (and, with it, an entry too large for the products below to be finite).
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j)
      if (std::abs(c(i, j)) > (1 + tol) * std::sqrt(c(i, i)) * std::sqrt(c(j, j)) + floor)
        return "not positive semi-definite";
  std::vector<std::array<double, 6>> columns;
  if (!pivoted_cholesky(c, columns)) return "not positive semi-definite";
  return {};
}

std::string pose_sigma_problem(const PoseSigma& s) {
  for (const double v : {s.xy_m, s.yaw_rad, s.z_m, s.roll_pitch_rad})
    if (!std::isfinite(v) || v < 0) return "each value must be finite and >= 0";
  const std::pair<std::string, double> deviations[4] = {
      {"x and y", s.xy_m}, {"yaw", s.yaw_rad}, {"z", s.z_m}, {"roll and pitch", s.roll_pitch_rad}};
  for (size_t k = 0; k < 4; ++k) {
    const std::string problem = deviation_problem(deviations[k].first, deviations[k].second, k % 2 == 1);
    if (!problem.empty()) return problem;
  }
  return pose_covariance_problem(PoseCovariance::from_sigma(s));
}

std::vector<PoseSigmaPoint> pose_sigma_points(const PoseCovariance& c) {
  const std::string problem = pose_covariance_problem(c);
  if (!problem.empty()) throw std::invalid_argument("pose covariance: " + problem);
  std::vector<std::array<double, 6>> columns;
  pivoted_cholesky(c, columns);
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
