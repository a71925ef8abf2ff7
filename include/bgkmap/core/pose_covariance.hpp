// Pose uncertainty of a scan: a Gaussian over a small rigid displacement of the scan about its
// sensor origin, and the sigma points over which the BGK maps take their expectation, of the
// scan's sub-map or of the kernel (docs/ALGORITHM.md, "Pose uncertainty").
//
// Convention: the true pose is the estimated one displaced by delta = (tx, ty, tz, rx, ry, rz):
// a translation t in the world's axes (m) and a rotation r (rotation vector, rad) about the world's
// axes through the estimated sensor origin o. A point p seen from the estimated pose truly lies at
//   o + t + Exp(r) (p - o),
// with delta ~ N(0, covariance). roll, pitch and yaw are rx, ry and rz (for small angles the
// usual Euler angles; the 3x3 planar form covers x, y and yaw).
#pragma once

#include <array>
#include <string>
#include <vector>

#include "bgkmap/core/grid.hpp"

namespace bgkmap {

// "XY,YAW" or "XY,YAW,Z,ROLLPITCH" (metres, radians; each finite and >= 0); throws
// std::invalid_argument with a one-line reason otherwise.
PoseSigma parse_pose_sigma(const std::string& text);
std::string to_string(const PoseSigma& sigma);

// 6x6, row-major, over (tx, ty, tz, rx, ry, rz) as above.
struct PoseCovariance {
  std::array<double, 36> m{};

  double operator()(int i, int j) const { return m[static_cast<size_t>(6 * i + j)]; }
  double& operator()(int i, int j) { return m[static_cast<size_t>(6 * i + j)]; }
  bool is_zero() const;

  static PoseCovariance from_sigma(const PoseSigma& sigma);
  // A planar covariance, row-major over (x, y, yaw): the rest of the 6x6 is zero.
  static PoseCovariance from_planar(const std::array<double, 9>& xy_yaw);
};

// Empty when `c` is a covariance (finite, symmetric within 1e-9 of its largest entry, positive
// semi-definite); otherwise why not, in one phrase.
std::string pose_covariance_problem(const PoseCovariance& c);

// One displacement of the quadrature and its weight.
struct PoseSigmaPoint {
  double weight = 0;
  Vec3d translation;  // t
  Vec3d rotation;     // r, a rotation vector
};

// The third-degree spherical-radial cubature rule (the unscented transform with kappa = 0):
// 2n points delta = +-sqrt(n) s_k, each of weight 1/(2n), where s_1..s_n are the columns of a
// square root of `c` (pivoted Cholesky, S S^T = c) and n its rank (pivots below 1e-12 of the
// largest variance end it). Their mean is 0 and their covariance c exactly (up to rounding);
// every weight is positive, so expected kernel weights stay non-negative and mixtures are
// mixtures. Empty for a zero
// covariance. `c` must pass pose_covariance_problem.
std::vector<PoseSigmaPoint> pose_sigma_points(const PoseCovariance& c);

// Exp(r): the rotation matrix of a rotation vector (Rodrigues), row-major.
std::array<double, 9> rotation_matrix(const Vec3d& r);

}  // namespace bgkmap
