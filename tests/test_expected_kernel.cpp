// gpom and wgpom under pose uncertainty by the expected kernel (--pose-fusion kernel) against
// plain references: the expected covariance E[k(d)], d ~ N(m, S), against a fine midpoint rule in
// the plane, a 1-D rule for a singular S and Monte Carlo in 3-D; the squared exponential's closed
// form against a Gauss-Hermite product rule on the same inputs; the inputs' position covariances
// against the displaced positions of the sigma points (beams: of the point itself) and Monte
// Carlo; zero covariance as the plain map bit for bit; and the whole map against a dense GP per
// cell with every datum (double precision).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "bgkmap/core/pose_covariance.hpp"
#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/methods/method.hpp"
#include "core/gauss_hermite.hpp"
#include "methods/gp/expected_kernel.hpp"
#include "methods/gp/gp_regression.hpp"
#include "methods/gpom/gpom_method.hpp"
#include "methods/gp/uncertain_inputs.hpp"
#include "methods/wgpom/warped_gp.hpp"
#include "support/dense_gp.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

using testing::cpu_backend;

GpHyperParams hyper(GpCovariance covariance, double ell, double signal, double noise) {
  GpHyperParams hp;
  hp.covariance = covariance;
  hp.ell_m = ell;
  hp.signal_var = signal;
  hp.noise_std = noise;
  return hp;
}

double norm(double x, double y, double z) { return std::sqrt(x * x + y * y + z * z); }

// E[k(|m + L z|)], z ~ N(0, I_2), L the lower Cholesky factor of the planar S: a midpoint rule of
// 1200 x 1200 cells over [-8, 8]^2 weighted by the normal density (no quadrature nodes shared
// with Gauss-Hermite).
double fine_planar_expectation(const Vec3d& m, double sxx, double sxy, double syy, const GpHyperParams& hp) {
  const double l11 = std::sqrt(sxx), l21 = sxy / l11, l22 = std::sqrt(syy - l21 * l21);
  const int n = 1200;
  const double h = 16.0 / n;
  std::vector<double> z(n), w(n);
  for (int i = 0; i < n; ++i) z[i] = -8 + (i + 0.5) * h, w[i] = h * std::exp(-0.5 * z[i] * z[i]) / std::sqrt(2 * M_PI);
  double sum = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const double dx = m.x + l11 * z[i], dy = m.y + l21 * z[i] + l22 * z[j];
      sum += w[i] * w[j] * gp_kernel(norm(dx, dy, m.z), hp);
    }
  return sum;
}

// The expected kernel of Matern 3/2 and the sparse kernel (l = 0.5 m): the matched Gauss-Hermite
// product rule of the method's order within 1e-3 s2 of the fine integral on these cases, S from
// far narrower than the kernel to as wide (sd 0.3 m; docs/ALGORITHM.md has the measurement that
// chose the order), and a 20-node rule within 1e-4 s2 (the same code converging to the reference).
TEST(ExpectedKernel, MaternAndSparseEqualAFineIntegralInThePlane) {
  struct Case {
    Vec3d m;
    double sxx, sxy, syy;
  };
  const Case cases[] = {{{0.1, -0.05, 0}, 0.01, 0.002, 0.004},
                        {{0.4, 0.3, 0}, 0.04, -0.01, 0.02},
                        {{0.0, 0.0, 0}, 0.0025, 0.0, 0.0025},
                        {{0.7, -0.1, 0}, 0.09, 0.03, 0.05},
                        {{0.05, 0.2, 0.0}, 0.0004, 0.0001, 0.0009},
                        {{0.3, 0.0, 0.0}, 0.09, 0.0, 0.0081}};
  for (const GpCovariance covariance : {GpCovariance::kMatern32, GpCovariance::kSparse}) {
    const GpHyperParams hp = hyper(covariance, 0.5, 1.3, 0.1);
    const ExpectedKernel method(hp, 2, kExpectedKernelOrder2d), fine(hp, 2, 20);
    for (const Case& c : cases) {
      const double ref = fine_planar_expectation(c.m, c.sxx, c.sxy, c.syy, hp);
      const PositionCovariance s{c.sxx, c.sxy, 0, c.syy, 0, 0};
      EXPECT_NEAR(method(c.m, s), ref, 1e-3 * hp.signal_var) << int(covariance) << " " << c.m.x << "," << c.m.y;
      EXPECT_NEAR(fine(c.m, s), ref, 1e-4 * hp.signal_var) << int(covariance) << " " << c.m.x << "," << c.m.y;
    }
  }
}

// A singular S (one direction, as a pure yaw gives a hit): against a 1-D midpoint rule.
TEST(ExpectedKernel, SingularCovarianceEqualsTheOneDimensionalIntegral) {
  const GpHyperParams hp = hyper(GpCovariance::kMatern32, 0.5, 1.0, 0.1);
  const double sd = 0.15, ux = 0.6, uy = 0.8;  // S = sd^2 u u^T
  const Vec3d m{0.2, -0.1, 0};
  const PositionCovariance s{sd * sd * ux * ux, sd * sd * ux * uy, 0, sd * sd * uy * uy, 0, 0};
  double ref = 0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    const double z = -8 + (i + 0.5) * 16.0 / n, w = 16.0 / n * std::exp(-0.5 * z * z) / std::sqrt(2 * M_PI);
    ref += w * gp_kernel(norm(m.x + sd * z * ux, m.y + sd * z * uy, 0), hp);
  }
  EXPECT_NEAR(ExpectedKernel(hp, 2, 20)(m, s), ref, 1e-4);
  EXPECT_NEAR(ExpectedKernel(hp, 3, 20)(m, s), ref, 1e-4);
  EXPECT_NEAR(ExpectedKernel(hp, 2, kExpectedKernelOrder2d)(m, s), ref, 1e-3);
}

// 3-D against Monte Carlo (400,000 samples in double, a fixed seed): within 5 standard errors.
TEST(ExpectedKernel, ThreeDimensionsEqualMonteCarlo) {
  const GpHyperParams hp = hyper(GpCovariance::kMatern32, 0.5, 1.0, 0.1);
  const Vec3d m{0.2, -0.15, 0.1};
  // S = A A^T for a full-rank A.
  const double a[9] = {0.1, 0, 0, 0.03, 0.08, 0, -0.02, 0.01, 0.06};
  const PositionCovariance s{a[0] * a[0], a[0] * a[3], a[0] * a[6], a[3] * a[3] + a[4] * a[4], a[3] * a[6] + a[4] * a[7],
                             a[6] * a[6] + a[7] * a[7] + a[8] * a[8]};
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal;
  double sum = 0, sum2 = 0;
  const int n = 400000;
  for (int i = 0; i < n; ++i) {
    const double z0 = normal(rng), z1 = normal(rng), z2 = normal(rng);
    const double k = gp_kernel(norm(m.x + a[0] * z0, m.y + a[3] * z0 + a[4] * z1, m.z + a[6] * z0 + a[7] * z1 + a[8] * z2), hp);
    sum += k;
    sum2 += k * k;
  }
  const double mean = sum / n, se = std::sqrt((sum2 / n - mean * mean) / n);
  EXPECT_NEAR(ExpectedKernel(hp, 3, 20)(m, s), mean, 5 * se);
  EXPECT_NEAR(ExpectedKernel(hp, 3, kExpectedKernelOrder3d)(m, s), mean, 5 * se + 1e-3);
}

// The squared exponential's closed form (IJRR eq. 19) against a 30-node Gauss-Hermite product rule
// of the plain SE kernel on the same inputs, in 2-D and 3-D, within 1e-10 s2.
TEST(ExpectedKernel, SquaredExponentialClosedFormEqualsGaussHermite) {
  const GpHyperParams hp = hyper(GpCovariance::kSquaredExponential, 0.4, 1.7, 0.1);
  const GaussHermite rule(30);
  const auto quadrature = [&](const Vec3d& m, const double l[9], int dims) {  // S = L L^T, L lower
    double sum = 0;
    const int n = rule.size();
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j)
        for (int k = 0; k < (dims == 3 ? n : 1); ++k) {
          const double z[3] = {std::sqrt(2.0) * rule.nodes()[i], std::sqrt(2.0) * rule.nodes()[j],
                               dims == 3 ? std::sqrt(2.0) * rule.nodes()[k] : 0.0};
          double w = rule.weights()[i] * rule.weights()[j] / M_PI;
          if (dims == 3) w *= rule.weights()[k] / std::sqrt(M_PI);
          sum += w * gp_kernel(norm(m.x + l[0] * z[0], m.y + l[3] * z[0] + l[4] * z[1],
                                    m.z + l[6] * z[0] + l[7] * z[1] + l[8] * z[2]),
                               hp);
        }
    return sum;
  };
  const double planar[9] = {0.2, 0, 0, 0.05, 0.1, 0, 0, 0, 0}, full[9] = {0.15, 0, 0, -0.04, 0.3, 0, 0.02, 0.05, 0.1};
  for (const Vec3d& m : {Vec3d{0, 0, 0}, Vec3d{0.3, -0.2, 0}, Vec3d{1.0, 0.5, 0}}) {
    const double* l = planar;
    const PositionCovariance s{l[0] * l[0], l[0] * l[3], 0, l[3] * l[3] + l[4] * l[4], 0, 0};
    EXPECT_NEAR(ExpectedKernel(hp, 2, kExpectedKernelOrder2d)(m, s), quadrature(m, l, 2), 1e-10 * hp.signal_var);
  }
  for (const Vec3d& m : {Vec3d{0, 0, 0}, Vec3d{0.3, -0.2, 0.1}, Vec3d{0.6, 0.5, -0.4}}) {
    const double* l = full;
    const PositionCovariance s{l[0] * l[0],
                               l[0] * l[3],
                               l[0] * l[6],
                               l[3] * l[3] + l[4] * l[4],
                               l[3] * l[6] + l[4] * l[7],
                               l[6] * l[6] + l[7] * l[7] + l[8] * l[8]};
    EXPECT_NEAR(ExpectedKernel(hp, 3, kExpectedKernelOrder3d)(m, s), quadrature(m, l, 3), 1e-10 * hp.signal_var);
  }
  // Its plain kernel is its formula.
  EXPECT_NEAR(gp_kernel(0.3, hp), 1.7 * std::exp(-0.5 * 0.3 * 0.3 / (0.4 * 0.4)), 1e-15);
}

// No uncertainty is the plain kernel, bit for bit, and so is a GP whose inputs all have zero covariance.
TEST(ExpectedKernel, ZeroCovarianceIsThePlainKernelBitForBit) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  for (const GpCovariance covariance : {GpCovariance::kMatern32, GpCovariance::kSparse, GpCovariance::kSquaredExponential}) {
    const GpHyperParams hp = hyper(covariance, 0.6, 1.1, 0.2);
    const ExpectedKernel ek(hp, 3, kExpectedKernelOrder3d);
    std::vector<Vec3d> x(30), q(5);
    for (Vec3d& p : x) p = {u(rng), u(rng), u(rng)};
    for (Vec3d& p : q) p = {u(rng), u(rng), u(rng)};
    std::vector<double> y(x.size());
    for (size_t i = 0; i < y.size(); ++i) y[i] = i % 3 ? -1.0 : 1.0;
    for (size_t i = 0; i < x.size(); ++i) {
      const double dx = x[i].x - q[0].x, dy = x[i].y - q[0].y, dz = x[i].z - q[0].z;
      EXPECT_EQ(ek({dx, dy, dz}, {}), gp_kernel(std::sqrt(dx * dx + dy * dy + dz * dz), hp));
    }
    const std::vector<PositionCovariance> zero(x.size());
    const InputUncertainty none{&zero, &ek};
    const std::vector<GpPrediction> plain = gp_predict(x, y, q, hp), expected = gp_predict(x, y, q, hp, &none);
    const std::vector<GpPrediction> plain_loo = gp_leave_one_out(x, y, hp), expected_loo = gp_leave_one_out(x, y, hp, &none);
    for (size_t t = 0; t < q.size(); ++t) {
      EXPECT_EQ(plain[t].mean, expected[t].mean);
      EXPECT_EQ(plain[t].variance, expected[t].variance);
    }
    for (size_t i = 0; i < x.size(); ++i) {
      EXPECT_EQ(plain_loo[i].mean, expected_loo[i].mean);
      EXPECT_EQ(plain_loo[i].variance, expected_loo[i].variance);
    }
  }
}

// Rotating v by the rotation vector r, by a unit quaternion (not the library's Rodrigues matrix).
Vec3d rotate(const Vec3d& r, const Vec3d& v) {
  const double angle = norm(r.x, r.y, r.z);
  if (angle == 0) return v;
  const double s = std::sin(angle / 2) / angle, w = std::cos(angle / 2);
  const double qx = r.x * s, qy = r.y * s, qz = r.z * s;
  // v' = v + 2 w (q x v) + 2 q x (q x v)
  const double cx = qy * v.z - qz * v.y, cy = qz * v.x - qx * v.z, cz = qx * v.y - qy * v.x;
  const double ddx = qy * cz - qz * cy, ddy = qz * cx - qx * cz, ddz = qx * cy - qy * cx;
  return {v.x + 2 * (w * cx + ddx), v.y + 2 * (w * cy + ddy), v.z + 2 * (w * cz + ddz)};
}

// p's positions o + t + R(p - o) under the sigma points (double; z kept on a planar map).
std::vector<Vec3d> displaced_positions(const std::vector<PoseSigmaPoint>& points, const Vec3d& o, const Vec3d& p,
                                       bool planar) {
  std::vector<Vec3d> at;
  for (const PoseSigmaPoint& s : points) {
    const Vec3d r = rotate(s.rotation, {p.x - o.x, p.y - o.y, p.z - o.z});
    at.push_back({o.x + s.translation.x + r.x, o.y + s.translation.y + r.y, planar ? p.z : o.z + s.translation.z + r.z});
  }
  return at;
}

// The weighted covariance of positions, one per sigma point.
PositionCovariance weighted_covariance(const std::vector<PoseSigmaPoint>& points, const std::vector<Vec3d>& at) {
  Vec3d mean;
  for (size_t h = 0; h < at.size(); ++h)
    mean = {mean.x + points[h].weight * at[h].x, mean.y + points[h].weight * at[h].y, mean.z + points[h].weight * at[h].z};
  PositionCovariance c;
  for (size_t h = 0; h < at.size(); ++h) {
    const double w = points[h].weight, dx = at[h].x - mean.x, dy = at[h].y - mean.y, dz = at[h].z - mean.z;
    c.xx += w * dx * dx, c.xy += w * dx * dy, c.xz += w * dx * dz, c.yy += w * dy * dy, c.yz += w * dy * dz, c.zz += w * dz * dz;
  }
  return c;
}

// The covariance of p's positions over the sigma points, p's own.
PositionCovariance displaced_covariance(const std::vector<PoseSigmaPoint>& points, const Vec3d& o, const Vec3d& p,
                                        bool planar) {
  return weighted_covariance(points, displaced_positions(points, o, p, planar));
}

// P C P, P = I - u u^T, by 3 x 3 products.
PositionCovariance projected(const PositionCovariance& c, const Vec3d& u) {
  const double m[3][3] = {{c.xx, c.xy, c.xz}, {c.xy, c.yy, c.yz}, {c.xz, c.yz, c.zz}}, v[3] = {u.x, u.y, u.z};
  double p[3][3], r[3][3] = {};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) p[i][j] = (i == j) - v[i] * v[j];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k)
        for (int l = 0; l < 3; ++l) r[i][j] += p[i][k] * m[k][l] * p[l][j];
  return {r[0][0], r[0][1], r[0][2], r[1][1], r[1][2], r[2][2]};
}

// The covariance of samples (normalised by their number).
PositionCovariance sample_covariance(const std::vector<Vec3d>& at) {
  const double n = double(at.size());
  Vec3d mean;
  for (const Vec3d& a : at) mean = {mean.x + a.x / n, mean.y + a.y / n, mean.z + a.z / n};
  PositionCovariance c;
  for (const Vec3d& a : at) {
    const double dx = a.x - mean.x, dy = a.y - mean.y, dz = a.z - mean.z;
    c.xx += dx * dx / n, c.xy += dx * dy / n, c.xz += dx * dz / n, c.yy += dy * dy / n, c.yz += dy * dz / n,
        c.zz += dz * dz / n;
  }
  return c;
}

void expect_covariance_near(const PositionCovariance& a, const PositionCovariance& b, double tol, const std::string& what) {
  EXPECT_NEAR(a.xx, b.xx, tol) << what;
  EXPECT_NEAR(a.xy, b.xy, tol) << what;
  EXPECT_NEAR(a.xz, b.xz, tol) << what;
  EXPECT_NEAR(a.yy, b.yy, tol) << what;
  EXPECT_NEAR(a.yz, b.yz, tol) << what;
  EXPECT_NEAR(a.zz, b.zz, tol) << what;
}

// Each hit's covariance is that of its displaced positions; each beam's covariance at t that of
// the displaced point at t itself (the (1 - t)^2, t^2, t (1 - t) formula is exact), within 1e-15
// m^2; and the sigma points' covariance of a hit is close to Monte Carlo's over the pose
// distribution (200,000 samples; the cubature rule is exact for the linear part, the rest is of
// the fourth order in the angles).
TEST(UncertainInputs, CovariancesOfHitsAndBeamsAreThoseOfTheirDisplacedPositions) {
  ScanObservations obs;
  obs.origin = {1.0f, 2.0f, 0.5f};
  obs.hits = {{4.0f, 2.5f, 0.7f}, {0.5f, -1.0f, 0.2f}, {1.0f, 2.0f, 3.0f}};
  obs.free_ends = {{3.0f, 2.4f, 0.6f}, {-2.0f, 0.0f, 0.5f}};
  PoseCovariance c;
  const double sd[6] = {0.05, 0.03, 0.02, 0.01, 0.015, 0.04};
  for (int i = 0; i < 6; ++i) c(i, i) = sd[i] * sd[i];
  c(0, 5) = c(5, 0) = 0.3 * sd[0] * sd[5];
  const std::vector<PoseSigmaPoint> points = pose_sigma_points(c);
  for (const bool planar : {false, true}) {
    std::vector<PositionCovariance> hits;
    std::vector<BeamCovariance> beams;
    append_input_covariances(obs, points, planar, SensorNoise{}, hits, beams);
    ASSERT_EQ(hits.size(), 3u);
    ASSERT_EQ(beams.size(), 2u);
    const Vec3d o{obs.origin.x, obs.origin.y, obs.origin.z};
    for (size_t i = 0; i < hits.size(); ++i)
      expect_covariance_near(hits[i], displaced_covariance(points, o, {obs.hits[i].x, obs.hits[i].y, obs.hits[i].z}, planar),
                             1e-15, "hit " + std::to_string(i));
    for (size_t b = 0; b < beams.size(); ++b)
      for (const double t : {0.0, 0.3, 0.5, 1.0}) {
        const Vec3f& e = obs.free_ends[b];
        const Vec3d p{o.x + t * (e.x - o.x), o.y + t * (e.y - o.y), o.z + t * (e.z - o.z)};
        expect_covariance_near(beams[b].at(t), displaced_covariance(points, o, p, planar), 1e-15,
                               "beam " + std::to_string(b) + " t " + std::to_string(t));
      }
    if (planar) {
      EXPECT_EQ(hits[0].zz, 0.0);
      EXPECT_EQ(beams[0].at(0.5).xz, 0.0);
    }
  }
  // Monte Carlo over delta ~ N(0, C): the hit 3 m from the origin.
  std::vector<PositionCovariance> hits;
  std::vector<BeamCovariance> beams;
  append_input_covariances(obs, points, false, SensorNoise{}, hits, beams);
  std::mt19937_64 rng(11);
  std::normal_distribution<double> normal;
  const int n = 200000;
  std::vector<Vec3d> at(n);
  const Vec3d p{obs.hits[0].x - obs.origin.x, obs.hits[0].y - obs.origin.y, obs.hits[0].z - obs.origin.z};
  for (Vec3d& a : at) {
    double z[6], d[6];
    for (double& v : z) v = normal(rng);
    for (int i = 0; i < 6; ++i) d[i] = sd[i] * z[i];
    d[5] = sd[5] * (0.3 * z[0] + std::sqrt(1 - 0.09) * z[5]);  // corr(x, yaw) = 0.3
    const Vec3d r = rotate({d[3], d[4], d[5]}, p);
    a = {d[0] + r.x, d[1] + r.y, d[2] + r.z};
  }
  const PositionCovariance mc = sample_covariance(at);
  // The variances are up to 0.017 m^2, Monte Carlo's standard error of one sqrt(2 / n) of it (5e-5).
  expect_covariance_near(hits[0], mc, 2e-4, "hit 0 against Monte Carlo");
}

// The sensor's noise: a return's covariance against Monte Carlo over (range, azimuth[, elevation])
// drawn independently, the return placed by spherical coordinates about the origin; and added to
// the pose part of hits and of beams' ends (a beam's origin has none).
TEST(UncertainInputs, SensorNoiseIsTheCovarianceOfTheNoisyReturn) {
  const Vec3f origin{1.0f, 2.0f, 0.5f};
  const SensorNoise noise{0.05, 0.01};
  for (const bool planar : {true, false}) {
    const Vec3f end = planar ? Vec3f{7.0f, -3.0f, 0.5f} : Vec3f{7.0f, -3.0f, 2.5f};
    const PositionCovariance c = sensor_covariance(origin, end, noise, planar);
    const double vx = end.x - origin.x, vy = end.y - origin.y, vz = planar ? 0.0 : end.z - origin.z;
    const double r = std::sqrt(vx * vx + vy * vy + vz * vz), azimuth = std::atan2(vy, vx),
                 elevation = std::asin(vz / r);
    std::mt19937_64 rng(planar ? 3 : 4);
    std::normal_distribution<double> normal;
    const int n = 400000;
    std::vector<Vec3d> at(n);
    for (Vec3d& a : at) {
      const double rr = r + noise.range_sigma * normal(rng), az = azimuth + noise.bearing_sigma * normal(rng);
      const double el = planar ? 0.0 : elevation + noise.bearing_sigma * normal(rng);
      a = {rr * std::cos(el) * std::cos(az), rr * std::cos(el) * std::sin(az), rr * std::sin(el)};
    }
    const PositionCovariance mc = sample_covariance(at);
    // Variances up to 0.0025 m^2 (range) and 0.0064 m^2 (8 m x 0.01 rad across): Monte Carlo's
    // standard error about sqrt(2 / n) of them, 1.4e-5; the cubature's own error is of 4th order.
    expect_covariance_near(c, mc, 6e-5, planar ? "planar return" : "3-D return");
    if (planar) {
      EXPECT_EQ(c.zz, 0.0);
    }
  }
  EXPECT_TRUE(sensor_covariance(origin, origin, noise, false).is_zero());
  EXPECT_TRUE(sensor_covariance(origin, {5.0f, 5.0f, 5.0f}, SensorNoise{}, false).is_zero());

  ScanObservations obs;
  obs.origin = origin;
  obs.hits = {{4.0f, 2.5f, 0.7f}};
  obs.free_ends = {{3.0f, 2.4f, 0.6f}};
  PoseCovariance pose;
  pose(0, 0) = pose(1, 1) = 0.01;
  const std::vector<PoseSigmaPoint> points = pose_sigma_points(pose);
  std::vector<PositionCovariance> plain_hits, noisy_hits;
  std::vector<BeamCovariance> plain_beams, noisy_beams;
  append_input_covariances(obs, points, false, SensorNoise{}, plain_hits, plain_beams);
  append_input_covariances(obs, points, false, noise, noisy_hits, noisy_beams);
  expect_covariance_near(noisy_hits[0], plain_hits[0] + sensor_covariance(origin, obs.hits[0], noise, false), 1e-18,
                         "hit");
  expect_covariance_near(noisy_beams[0].at(0.0), plain_beams[0].at(0.0), 1e-18, "beam origin");
  expect_covariance_near(noisy_beams[0].end, plain_beams[0].end + sensor_covariance(origin, obs.free_ends[0], noise, false),
                         1e-18, "beam end");
}

// A segment's point nearest to a query q on it: under each sigma point of a small pose
// uncertainty the displaced segment's nearest point to q (found afresh), and the covariance of those
// points against across_segment(at(t)): within 2 % of the largest variance (the rest is of second
// order in the displacement, about 1e-3 of it here). Along the segment nothing is left, where
// at(t) itself has most of the variance (a translation along the beam). (For q off the segment by
// r the nearest point also moves along it, by r times the beam's rotation, which across_segment
// leaves out: docs/ALGORITHM.md.)
TEST(UncertainInputs, AcrossSegmentIsTheCovarianceOfTheDisplacedSegmentsNearestPoint) {
  const Vec3d o{1.0, 2.0, 0.5}, e{6.0, 3.0, 0.9};
  PoseCovariance c;
  const double sd[6] = {2e-3, 5e-4, 3e-4, 2e-4, 1e-4, 3e-4};
  for (int i = 0; i < 6; ++i) c(i, i) = sd[i] * sd[i];
  const std::vector<PoseSigmaPoint> points = pose_sigma_points(c);
  ScanObservations obs;
  obs.origin = {float(o.x), float(o.y), float(o.z)};
  obs.free_ends = {{float(e.x), float(e.y), float(e.z)}};
  std::vector<PositionCovariance> hits;
  std::vector<BeamCovariance> beams;
  append_input_covariances(obs, points, false, SensorNoise{}, hits, beams);
  const Vec3d oo{obs.origin.x, obs.origin.y, obs.origin.z}, ee{obs.free_ends[0].x, obs.free_ends[0].y, obs.free_ends[0].z};
  const Vec3d d{ee.x - oo.x, ee.y - oo.y, ee.z - oo.z};
  const double len = norm(d.x, d.y, d.z);
  const Vec3d u{d.x / len, d.y / len, d.z / len};
  const double t = 0.45;
  const Vec3d q{oo.x + t * d.x, oo.y + t * d.y, oo.z + t * d.z};
  const std::vector<Vec3d> a = displaced_positions(points, oo, oo, false), b = displaced_positions(points, oo, ee, false);
  std::vector<Vec3d> nearest;
  for (size_t h = 0; h < points.size(); ++h) {
    const Vec3d ab{b[h].x - a[h].x, b[h].y - a[h].y, b[h].z - a[h].z};
    const double s = ((q.x - a[h].x) * ab.x + (q.y - a[h].y) * ab.y + (q.z - a[h].z) * ab.z) /
                     (ab.x * ab.x + ab.y * ab.y + ab.z * ab.z);
    nearest.push_back({a[h].x + s * ab.x, a[h].y + s * ab.y, a[h].z + s * ab.z});
  }
  const PositionCovariance reference = weighted_covariance(points, nearest), point = beams[0].at(t);
  const PositionCovariance across = across_segment(point, u);
  const double largest = std::max({reference.xx, reference.yy, reference.zz});
  expect_covariance_near(across, reference, 0.02 * largest, "nearest point");
  const auto along = [&](const PositionCovariance& m) {
    return u.x * (m.xx * u.x + m.xy * u.y + m.xz * u.z) + u.y * (m.xy * u.x + m.yy * u.y + m.yz * u.z) +
           u.z * (m.xz * u.x + m.yz * u.y + m.zz * u.z);
  };
  EXPECT_NEAR(along(across), 0.0, 1e-12 * largest);
  EXPECT_GT(along(point), 0.5 * (point.xx + point.yy + point.zz));
  expect_covariance_near(across, projected(point, u), 1e-18, "P C P");
}

// The covariance of the difference of two inputs that move together: ScanMotion's displacements
// (centred) in difference_covariances, against the covariance over the sigma points of the
// difference of the two displaced positions (quaternion rotations), within 1e-15 m^2: two hits of
// one scan, a hit and a segment's inner point (its displacement across the segment), two hits of
// two scans whose sigma points are paired (proportional covariances, one rank). In no group (or
// in two groups): S_i + S_j.
TEST(UncertainInputs, DifferenceCovariancesAreThoseOfTheDisplacedDifferences) {
  PoseCovariance c;
  c(0, 0) = 0.04 * 0.04, c(1, 1) = 0.03 * 0.03, c(5, 5) = 0.02 * 0.02, c(0, 5) = c(5, 0) = 0.3 * 0.04 * 0.02;
  PoseCovariance c2 = c;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j) c2(i, j) *= 2.5;
  const std::vector<std::vector<PoseSigmaPoint>> points{pose_sigma_points(c), pose_sigma_points(c2)};
  ASSERT_EQ(points[0].size(), points[1].size());
  const Vec3f o0{1.0f, 2.0f, 0.5f}, o1{-3.0f, 1.0f, 0.5f};
  const std::vector<Vec3d> origins{{o0.x, o0.y, o0.z}, {o1.x, o1.y, o1.z}};
  const std::vector<ScanMotion> motions{ScanMotion(o0, points[0], true), ScanMotion(o1, points[1], true)};
  // Inputs: (scan, position, direction across which it moves: zero for a hit).
  struct Input {
    int scan;
    Vec3d p, u;
  };
  const double r = 1 / std::sqrt(2.0);
  const std::vector<Input> inputs{{0, {4.0, 2.5, 0.5}, {}}, {0, {4.2, 3.1, 0.5}, {}}, {0, {3.0, 4.0, 0.5}, {r, r, 0}},
                                  {1, {4.1, 2.0, 0.5}, {}}};
  SharedMotion shared;
  shared.points = points[0].size();
  std::vector<PositionCovariance> marginal;
  std::vector<std::vector<Vec3d>> moved;  // each input's displaced positions (the inner point: moved across)
  for (const Input& in : inputs) {
    std::vector<Vec3d> at = displaced_positions(points[in.scan], origins[in.scan], in.p, true);
    for (Vec3d& a : at) {
      const Vec3d m{a.x - in.p.x, a.y - in.p.y, a.z - in.p.z};
      const double along = m.x * in.u.x + m.y * in.u.y + m.z * in.u.z;
      a = {in.p.x + m.x - along * in.u.x, in.p.y + m.y - along * in.u.y, in.p.z + m.z - along * in.u.z};
    }
    moved.push_back(at);
    marginal.push_back(weighted_covariance(points[in.scan], at));
    std::vector<Vec3d> d(shared.points);
    motions[in.scan].displacements(in.p, d.data());
    Vec3d mean;
    for (Vec3d& v : d) {
      const double along = v.x * in.u.x + v.y * in.u.y + v.z * in.u.z;
      v = {v.x - along * in.u.x, v.y - along * in.u.y, v.z - along * in.u.z};
      mean = {mean.x + v.x / double(d.size()), mean.y + v.y / double(d.size()), mean.z + v.z / double(d.size())};
    }
    for (const Vec3d& v : d) shared.moves.push_back({v.x - mean.x, v.y - mean.y, v.z - mean.z});
    shared.weight.push_back(points[in.scan][0].weight);
  }
  const size_t n = inputs.size();
  for (const bool paired : {false, true}) {
    shared.group.clear();
    for (const Input& in : inputs) shared.group.push_back(paired ? 0u : uint32_t(in.scan));
    std::vector<PositionCovariance> out;
    difference_covariances(marginal, shared, out);
    ASSERT_EQ(out.size(), n * n);
    for (size_t i = 0; i < n; ++i)
      for (size_t j = 0; j < n; ++j) {
        if (i == j) continue;
        const std::string what = std::to_string(i) + "-" + std::to_string(j) + (paired ? " paired" : " per scan");
        if (!paired && inputs[i].scan != inputs[j].scan) {
          expect_covariance_near(out[i * n + j], marginal[i] + marginal[j], 1e-18, what);
          continue;
        }
        std::vector<Vec3d> difference;
        for (size_t h = 0; h < moved[i].size(); ++h)
          difference.push_back({moved[i][h].x - moved[j][h].x, moved[i][h].y - moved[j][h].y, moved[i][h].z - moved[j][h].z});
        expect_covariance_near(out[i * n + j], weighted_covariance(points[0], difference), 1e-15, what);
      }
  }
  // Two hits 0.6 m apart on one scan: their difference is far surer than S_i + S_j says.
  shared.group.assign(n, 0);
  std::vector<PositionCovariance> out;
  difference_covariances(marginal, shared, out);
  EXPECT_LT(out[1].xx + out[1].yy, 0.05 * (marginal[0].xx + marginal[0].yy + marginal[1].xx + marginal[1].yy));
  shared.group.assign(n, SharedMotion::kNoGroup);
  difference_covariances(marginal, shared, out);
  expect_covariance_near(out[1], marginal[0] + marginal[1], 1e-18, "no group");
}

// The whole map: two planar scans, the first certain (or, with `both`, uncertain too, its
// covariance 0.6 times the second's), the second with a planar covariance, every datum in every
// local model. The reference per cell: the dense GP (warped for wgpom) on every hit and every
// beam's nearest point. Each input's displacements are those of its displaced positions
// (displaced_positions; a beam's inner point keeps only its motion across the beam), its
// covariance S_i theirs; K_ij = E[k] over D_ij off the diagonal, k(0) + sn^2 on it, k*_i = E[k]
// over S_i, where D_ij is the covariance of the difference of the two inputs' displaced positions
// over the paired sigma points when they move together (--gp-input-correlation scan: one scan;
// trajectory: any two uncertain scans) and S_i + S_j otherwise. Known where a datum is within reach
// (the estimates' positions, as plain gpom). Tolerance 1e-9 (double precision throughout).
// With sensor noise every input of both scans adds its return's noise, independent of all else: a
// hit its own, a beam's point at fraction t of the segment t^2 times its end's (sensor_covariance),
// across the beam for an inner point.
void expect_dense_expected_kernel(const std::string& name, GpCovariance covariance, const TanhWarp* warp,
                                  const SensorNoise& sensor = {}, const std::string& correlation = "trajectory",
                                  bool both = false) {
  BuildParams params = testing::small_planar_params();
  params.preprocess.pose_fusion = PoseFusion::kExpectedKernel;
  MethodParams mp = testing::dense_reference_method_params();
  mp.set("gp-range-sigma", sensor.range_sigma);
  mp.set("gp-bearing-sigma", sensor.bearing_sigma);
  mp.set("gp-covariance", covariance == GpCovariance::kSquaredExponential ? "se" : "matern");
  mp.set("gp-input-correlation", correlation);
  std::vector<Scan> scans = testing::two_planar_scans();
  const std::array<double, 9> planar{0.03 * 0.03, 0.0002, 0, 0.0002, 0.04 * 0.04, 0, 0, 0, 0.08 * 0.08};
  scans[1].pose_covariance = PoseCovariance::from_planar(planar);
  if (both) {
    std::array<double, 9> smaller = planar;
    for (double& v : smaller) v *= 0.6;
    scans[0].pose_covariance = PoseCovariance::from_planar(smaller);
  }
  auto method = warp ? make_wgpom_method(params, mp, cpu_backend(), *warp) : make_method(name, params, mp, cpu_backend());
  for (const Scan& scan : scans) method->insert(scan);
  method->finish();

  std::vector<ScanObservations> obs(2);
  PreprocessCounts counts;
  for (int s = 0; s < 2; ++s) preprocess_scan(scans[s], params.preprocess, obs[s], counts);
  const std::vector<std::vector<PoseSigmaPoint>> points{
      both ? pose_sigma_points(*scans[0].pose_covariance) : std::vector<PoseSigmaPoint>{},
      pose_sigma_points(*scans[1].pose_covariance)};
  const GpHyperParams hp = hyper(covariance, 0.3, 1.0, 0.1);
  const ExpectedKernel ek(hp, 2, kExpectedKernelOrder2d);
  const GaussHermite rule(20);
  int compared = 0, unknown = 0;
  for (int cy = 0; cy < 32; ++cy)
    for (int cx = 0; cx < 32; ++cx) {
      const Vec3d q{(cx + 0.5) * 0.1, (cy + 0.5) * 0.1, 0.0};
      std::vector<Vec3d> x;
      std::vector<PositionCovariance> s, noise;  // per input: S_i, and its sensor noise part
      std::vector<std::vector<Vec3d>> moved;       // per input: its displaced positions (none: certain)
      std::vector<int> scan_of;
      std::vector<double> y;
      for (int scan = 0; scan < 2; ++scan) {
        const Vec3d o{obs[scan].origin.x, obs[scan].origin.y, obs[scan].origin.z};
        // An input at p (moving across u, if not zero) with sensor noise n.
        const auto add = [&](const Vec3d& p, const Vec3d& u, const PositionCovariance& n, double label) {
          std::vector<Vec3d> at = points[scan].empty() ? std::vector<Vec3d>{} : displaced_positions(points[scan], o, p, true);
          for (Vec3d& a : at) {
            const Vec3d m{a.x - p.x, a.y - p.y, a.z - p.z};
            const double along = m.x * u.x + m.y * u.y + m.z * u.z;
            a = {p.x + m.x - along * u.x, p.y + m.y - along * u.y, p.z + m.z - along * u.z};
          }
          x.push_back(p);
          noise.push_back(projected(n, u));
          s.push_back((at.empty() ? PositionCovariance{} : weighted_covariance(points[scan], at)) + noise.back());
          moved.push_back(at);
          scan_of.push_back(scan);
          y.push_back(label);
        };
        for (const Vec3f& h : obs[scan].hits) add({h.x, h.y, h.z}, {}, sensor_covariance(obs[scan].origin, h, sensor, true), 1);
        for (const Vec3f& e : obs[scan].free_ends) {
          const Vec3d d{e.x - o.x, e.y - o.y, e.z - o.z};
          const double t = std::clamp(((q.x - o.x) * d.x + (q.y - o.y) * d.y) / (d.x * d.x + d.y * d.y), 0.0, 1.0);
          const double len = std::hypot(d.x, d.y);
          const Vec3d u = t > 0 && t < 1 ? Vec3d{d.x / len, d.y / len, 0.0} : Vec3d{};
          const PositionCovariance end = sensor_covariance(obs[scan].origin, e, sensor, true);
          add({o.x + t * d.x, o.y + t * d.y, o.z + t * d.z}, u,
              PositionCovariance{t * t * end.xx, t * t * end.xy, t * t * end.xz, t * t * end.yy, t * t * end.yz, t * t * end.zz},
              -1);
        }
      }
      // D_ij: the displaced differences' covariance when i and j move together.
      const auto difference = [&](size_t i, size_t j) {
        const bool together = !moved[i].empty() && !moved[j].empty() &&
                              (correlation == "trajectory" || (correlation == "scan" && scan_of[i] == scan_of[j]));
        if (!together) return s[i] + s[j];
        std::vector<Vec3d> d;
        for (size_t h = 0; h < moved[i].size(); ++h)
          d.push_back({moved[i][h].x - moved[j][h].x, moved[i][h].y - moved[j][h].y, moved[i][h].z - moved[j][h].z});
        return weighted_covariance(points[1], d) + noise[i] + noise[j];
      };
      double nearest = INFINITY;
      for (const Vec3d& p : x) nearest = std::min(nearest, std::hypot(p.x - q.x, p.y - q.y));
      const std::optional<CellEstimate> e = method->estimate(q.x, q.y, 0.0);
      if (nearest > 0.3 + 1e-9) {
        EXPECT_FALSE(e.has_value()) << cx << "," << cy;
        ++unknown;
        continue;
      }
      if (nearest > 0.3 - 1e-9) continue;  // on the reach boundary: float rounding decides
      ASSERT_TRUE(e.has_value()) << cx << "," << cy;
      const size_t n = x.size();
      std::vector<std::vector<double>> k(n, std::vector<double>(n));
      std::vector<double> ks(n);
      for (size_t i = 0; i < n; ++i) {
        for (size_t j = 0; j < n; ++j)
          k[i][j] = i == j ? gp_kernel(0, hp) + hp.noise_std * hp.noise_std
                           : ek({x[i].x - x[j].x, x[i].y - x[j].y, x[i].z - x[j].z}, difference(i, j));
        ks[i] = ek({x[i].x - q.x, x[i].y - q.y, x[i].z - q.z}, s[i]);
      }
      if (warp)
        for (double& label : y) label = warp->value(label);
      GpPrediction p = testing::dense_gp(k, ks, gp_kernel(0, hp), y);
      if (warp) p = unwarp_prediction(p.mean, p.variance, *warp, rule);
      EXPECT_NEAR(*e->gp_mean, p.mean, 1e-9) << cx << "," << cy;
      EXPECT_NEAR(*e->variance, p.variance, 1e-9) << cx << "," << cy;
      ++compared;
    }
  EXPECT_GT(compared, 100);
  EXPECT_GT(unknown, 100);
  EXPECT_NE(method->backend().device.find("expected kernel over uncertain inputs"), std::string::npos);
}

TEST(GpomExpectedKernel, EqualsTheDenseGpWithExpectedCovariancesIn2D) {
  expect_dense_expected_kernel("gpom", GpCovariance::kMatern32, nullptr);
}

TEST(GpomExpectedKernel, EachInputCorrelationEqualsTheDenseGpWithBothScansUncertain) {
  for (const std::string correlation : {"independent", "scan", "trajectory"}) {
    SCOPED_TRACE(correlation);
    expect_dense_expected_kernel("gpom", GpCovariance::kMatern32, nullptr, SensorNoise{0.02, 0.03}, correlation, true);
  }
}

TEST(GpomExpectedKernel, SensorNoiseEqualsTheDenseGpIn2D) {
  expect_dense_expected_kernel("gpom", GpCovariance::kMatern32, nullptr, SensorNoise{0.02, 0.03});
}

TEST(GpomExpectedKernel, SquaredExponentialEqualsTheDenseGpIn2D) {
  expect_dense_expected_kernel("gpom", GpCovariance::kSquaredExponential, nullptr);
}

TEST(WgpomExpectedKernel, EqualsTheDenseWarpedGpWithExpectedCovariancesIn2D) {
  TanhWarp warp;
  warp.d = 0.4;
  warp.a = {1.5, 0.7};
  warp.b = {2.0, 0.8};
  warp.c = {-0.9, 0.6};
  expect_dense_expected_kernel("wgpom", GpCovariance::kMatern32, &warp);
}

// Under the expected kernel scans of different ranks are accepted (nothing is paired); a zero
// covariance gives the plain map (test_gpom's GpomPoseUncertainty.ZeroCovarianceGivesThePlainMapExactly).
TEST(GpomExpectedKernel, ScansOfDifferentRanksAreAcceptedUnlessPaired) {
  for (const std::string name : {"gpom", "wgpom"}) {
    BuildParams params = testing::small_planar_params();
    params.preprocess.pose_fusion = PoseFusion::kExpectedKernel;
    std::vector<Scan> scans = testing::two_planar_scans();
    scans[0].pose_covariance = PoseCovariance::from_planar({0.01, 0, 0, 0, 0.01, 0, 0, 0, 0.001});
    scans[1].pose_covariance = PoseCovariance::from_planar({0.01, 0, 0, 0, 0.01, 0, 0, 0, 0});
    for (const std::string correlation : {"independent", "scan"}) {
      MethodParams mp;
      mp.set("gp-input-correlation", correlation);
      auto ranks = make_method(name, params, mp, cpu_backend());
      for (const Scan& scan : scans) ranks->insert(scan);
      EXPECT_GT(ranks->known_cells(), 100u) << name << " " << correlation;
    }
    MethodParams unknown;
    EXPECT_THROW(unknown.set("gp-input-correlation", "pairs"), std::invalid_argument);
    auto paired = make_method(name, params, MethodParams{}, cpu_backend());
    paired->insert(scans[0]);
    try {
      paired->insert(scans[1]);
      ADD_FAILURE() << name << ": scans of ranks 3 and 2 paired";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("scan 2's pose covariance has rank 2, the earlier uncertain scans' 3 "
                                           "(--gp-input-correlation trajectory pairs"),
                std::string::npos)
          << e.what();
    }
  }
}

}  // namespace
}  // namespace bgkmap
