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

// The largest standard deviations a pose uncertainty may have. A translation's: the map's key
// range (kCoordinateLimitM), as a scan displaced farther has no cells to land in. A rotation's:
// pi rad, half a turn, beyond which the sigma points wrap around and say nothing of the heading.
// Larger ones cannot be meant (squared, some overflow on the way) and are refused.
constexpr double kMaxPoseTranslationSigmaM = kCoordinateLimitM;
constexpr double kMaxPoseRotationSigmaRad = 3.141592653589793;

// How far a covariance may stray from symmetric positive semi-definite and still be taken, in
// units of its own scale sqrt(c_ii c_jj): files written by other tools hold rounded numbers
// (7 significant digits put a correlation of 1 up to about 1e-6 off). Asymmetry up to this is
// rounding; what the pivoted Cholesky leaves of an axis's variance, below this fraction of it, is
// zero (the axis is explained by the others: a rank-deficient covariance), and refused only
// below minus this fraction (a correlation of 1.01 is).
constexpr double kPoseCovarianceTolerance = 1e-5;

// "XY,YAW" or "XY,YAW,Z,ROLLPITCH" (metres, radians; each finite, >= 0 and within the bounds
// above, pose_sigma_problem); throws std::invalid_argument with a one-line reason otherwise,
// "NAME 'TEXT': why" (NAME names where the text came from, e.g. the flag).
PoseSigma parse_pose_sigma(const std::string& text, const std::string& name = "pose sigma");
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

// Empty when `c` is a pose covariance that can be meant: finite, its standard deviations within
// kMaxPoseTranslationSigmaM and kMaxPoseRotationSigmaRad, symmetric and positive semi-definite
// within kPoseCovarianceTolerance; otherwise why not, in one phrase. Every way a pose uncertainty
// comes in (--pose-sigma and the config's pose_sigma through pose_sigma_problem, --pose-covariance
// and --poses lines, a Scan's own) is checked by this one function.
std::string pose_covariance_problem(const PoseCovariance& c);
// The same for constant standard deviations, checked before they are squared.
std::string pose_sigma_problem(const PoseSigma& sigma);

// One displacement of the quadrature and its weight.
struct PoseSigmaPoint {
  double weight = 0;
  Vec3d translation;  // t
  Vec3d rotation;     // r, a rotation vector
};

// The third-degree spherical-radial cubature rule (the unscented transform with kappa = 0):
// 2n points delta = +-sqrt(n) s_k, each of weight 1/(2n), where s_1..s_n are the columns of a
// square root of `c` (pivoted Cholesky, S S^T = c, the largest remaining fraction of an axis's
// own variance first, ties by the largest variance) and n its rank (an axis whose remaining
// variance is below kPoseCovarianceTolerance of its own is explained by the others). Their
// mean is 0 and their covariance c (up to rounding, and the tolerance); every weight is
// positive, so expected kernel weights stay non-negative and mixtures are mixtures. Empty for a
// zero covariance. Throws std::invalid_argument when `c` fails pose_covariance_problem.
std::vector<PoseSigmaPoint> pose_sigma_points(const PoseCovariance& c);

// Exp(r): the rotation matrix of a rotation vector (Rodrigues), row-major.
std::array<double, 9> rotation_matrix(const Vec3d& r);

}  // namespace bgkmap
