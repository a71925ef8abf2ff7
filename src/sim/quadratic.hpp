// Roots of a t^2 + b t + c, computed without cancellation; shared by the curved primitives.
#pragma once

#include <cmath>
#include <optional>

namespace bgkmap::sim {

// The interval where a t^2 + b t + c <= 0 for a > 0; false when it is empty.
inline bool nonpositive_interval(double a, double b, double c, double& r0, double& r1) {
  const double disc = b * b - 4 * a * c;
  if (disc < 0) return false;
  const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
  if (q == 0) {  // b = 0 and c = 0: a double root at 0
    r0 = r1 = 0;
    return true;
  }
  const double x0 = q / a, x1 = c / q;
  r0 = std::fmin(x0, x1);
  r1 = std::fmax(x0, x1);
  return true;
}

// Smallest t in [lo, hi] with a t^2 + b t + c <= 0 (lo itself when it is non-positive there).
inline std::optional<double> first_nonpositive(double a, double b, double c, double lo, double hi) {
  if (lo > hi) return std::nullopt;
  if (a == 0) {
    if (b * lo + c <= 0) return lo;
    if (b >= 0) return std::nullopt;  // non-decreasing and positive at lo
    const double t = std::fmax(-c / b, lo);
    return t <= hi ? std::optional<double>(t) : std::nullopt;
  }
  if (a > 0) {
    double r0, r1;
    if (!nonpositive_interval(a, b, c, r0, r1) || r1 < lo) return std::nullopt;
    const double t = std::fmax(r0, lo);
    return t <= hi ? std::optional<double>(t) : std::nullopt;
  }
  // a < 0: non-positive outside (r0, r1); the roots of -(...) are the same.
  double r0, r1;
  if (!nonpositive_interval(-a, -b, -c, r0, r1)) return lo;  // negative everywhere
  const double t = r0 >= lo ? lo : std::fmax(r1, lo);
  return t <= hi ? std::optional<double>(t) : std::nullopt;
}

}  // namespace bgkmap::sim
