// --method bhm: the variational update against a dense implementation written out here, the
// sequential model's algebra, its predictive probabilities and variances, 2-D / 3-D scans, and the
// command end to end on simulated data.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "bgkmap/io/errors.hpp"
#include "bgkmap/methods/method.hpp"
#include "methods/bhm/bhm_gamma_search.hpp"
#include "methods/bhm/bhm_model.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

// A tiny 2-D problem inside hinge block (0, 0): hinges (i, j) * 0.5 m, i, j in [0, 8).
BhmParams tiny_params() {
  BhmParams p;
  p.spacing_m = 0.5;
  p.gamma = 6.0;
  p.prior_var = 0.8;
  p.em_iterations = 4;
  p.block_side = 8;
  p.dims = 2;
  p.plane_z = 0.25;
  p.threads = 1;
  return p;
}

void tiny_scan(uint32_t seed, int n, std::vector<Vec3d>& points, std::vector<double>& labels) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> at(1.35, 2.15);
  for (int k = 0; k < n; ++k) {
    points.push_back({at(rng), at(rng), 0.25});
    labels.push_back(points.back().x + 0.3 * points.back().y > 2.3 ? 1.0 : 0.0);
  }
}

// Phi written out from the definition: exp(-gamma |x - h|^2) where at least the cutoff, else 0;
// column i + 8 j is hinge (0.5 i, 0.5 j).
Eigen::MatrixXd dense_features(const std::vector<Vec3d>& points, const BhmParams& p) {
  Eigen::MatrixXd phi = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(points.size()), 64);
  for (size_t r = 0; r < points.size(); ++r)
    for (int j = 0; j < 8; ++j)
      for (int i = 0; i < 8; ++i) {
        const double dx = points[r].x - 0.5 * i, dy = points[r].y - 0.5 * j;
        const double v = std::exp(-p.gamma * (dx * dx + dy * dy));
        if (v >= kFeatureCutoff) phi(static_cast<Eigen::Index>(r), i + 8 * j) = v;
      }
  return phi;
}

// The paper's update with full covariance, dense, in the order it is written:
// xi^2 = diag(Phi (S + m m^T) Phi^T); S^-1 = S0^-1 + 2 Phi^T L Phi; m = S (S0^-1 m0 + Phi^T (y - 1/2)).
void dense_update(const Eigen::MatrixXd& phi, const std::vector<double>& labels, int iterations, Eigen::VectorXd& mean,
                  Eigen::MatrixXd& cov) {
  const Eigen::MatrixXd prior_precision = cov.inverse();
  const Eigen::VectorXd prior_rhs = prior_precision * mean;
  Eigen::VectorXd y_half(phi.rows());
  for (Eigen::Index r = 0; r < phi.rows(); ++r) y_half[r] = labels[r] - 0.5;
  for (int it = 0; it < iterations; ++it) {
    const Eigen::MatrixXd second_moment = cov + mean * mean.transpose();
    Eigen::VectorXd lambda(phi.rows());
    for (Eigen::Index r = 0; r < phi.rows(); ++r) {
      const double xi = std::sqrt(phi.row(r) * second_moment * phi.row(r).transpose());
      lambda[r] = std::tanh(xi / 2) / (4 * xi);
    }
    const Eigen::MatrixXd precision = prior_precision + 2 * phi.transpose() * lambda.asDiagonal() * phi;
    cov = precision.inverse();
    mean = cov * (prior_rhs + phi.transpose() * y_half);
  }
}

TEST(BhmModel, VariationalUpdatesEqualTheDenseFullCovarianceUpdate) {
  const BhmParams p = tiny_params();
  BhmModel model(p);
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(64);
  Eigen::MatrixXd cov = Eigen::MatrixXd::Identity(64, 64) * p.prior_var;
  // Two scans: the second's prior is the first's posterior.
  for (uint32_t scan = 0; scan < 2; ++scan) {
    std::vector<Vec3d> points;
    std::vector<double> labels;
    tiny_scan(7 + scan, 40, points, labels);
    model.update(points, labels);
    dense_update(dense_features(points, p), labels, p.em_iterations, mean, cov);
    ASSERT_EQ(model.block_count(), 1u);  // every feature in block (0, 0): one full covariance
    ASSERT_EQ(model.block_key(0), (BlockKey{0, 0, 0}));
    EXPECT_LT((model.block_mean(0) - mean).cwiseAbs().maxCoeff(), 1e-9) << "scan " << scan;
    EXPECT_LT((model.block_cov(0) - cov).cwiseAbs().maxCoeff(), 1e-9) << "scan " << scan;
  }
  EXPECT_GT(mean.cwiseAbs().maxCoeff(), 0.5);  // the data moved it
  // Predictions: phi^T m, phi^T S phi and the probit-approximated sigmoid.
  const std::vector<Vec3d> queries = {{1.6, 1.7, 0.25}, {2.0, 1.4, 0.25}, {1.8, 2.1, 0.25}};
  const Eigen::MatrixXd phi = dense_features(queries, p);
  for (size_t q = 0; q < queries.size(); ++q) {
    const std::optional<BhmLogit> a = model.logit(queries[q]);
    ASSERT_TRUE(a.has_value());
    const Eigen::VectorXd f = phi.row(static_cast<Eigen::Index>(q)).transpose();
    const double m = f.dot(mean), v = f.dot(cov * f);
    EXPECT_NEAR(a->mean, m, 1e-9);
    EXPECT_NEAR(a->variance, v, 1e-9);
    EXPECT_NEAR(BhmModel::probability(*a), 1 / (1 + std::exp(-m / std::sqrt(1 + M_PI * v / 8))), 1e-12);
  }
}

// With xi held fixed the bound makes the likelihood Gaussian in w: conjugate, so updating on two
// halves in turn equals one update on the whole.
TEST(BhmModel, TwoHalfScansEqualTheWholeScanAtFixedXi) {
  std::vector<Vec3d> points;
  std::vector<double> labels;
  tiny_scan(3, 60, points, labels);
  std::vector<double> xi(points.size());
  for (size_t k = 0; k < xi.size(); ++k) xi[k] = 0.3 + 0.05 * static_cast<double>(k % 17);
  const auto half = [&](size_t from, size_t to, std::vector<Vec3d>& pts, std::vector<double>& lab,
                        std::vector<double>& x) {
    pts.assign(points.begin() + from, points.begin() + to);
    lab.assign(labels.begin() + from, labels.begin() + to);
    x.assign(xi.begin() + from, xi.begin() + to);
  };
  BhmModel whole(tiny_params()), halves(tiny_params());
  whole.update(points, labels, &xi);
  std::vector<Vec3d> pts;
  std::vector<double> lab, x;
  half(0, 30, pts, lab, x);
  halves.update(pts, lab, &x);
  half(30, 60, pts, lab, x);
  halves.update(pts, lab, &x);
  ASSERT_EQ(whole.block_count(), 1u);
  ASSERT_EQ(halves.block_count(), 1u);
  EXPECT_LT((whole.block_mean(0) - halves.block_mean(0)).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((whole.block_cov(0) - halves.block_cov(0)).cwiseAbs().maxCoeff(), 1e-9);
}

// Blocks no point reaches from both halves are independent in q: EM on two half-scans far apart
// equals EM on the whole scan, block for block.
TEST(BhmModel, HalfScansInSeparateBlocksEqualTheWholeScan) {
  BhmParams p = tiny_params();
  p.threads = 2;
  std::vector<Vec3d> near_points, far_points;
  std::vector<double> near_labels, far_labels;
  tiny_scan(11, 50, near_points, near_labels);
  tiny_scan(12, 50, far_points, far_labels);
  for (Vec3d& x : far_points) x.x += 20.0;  // hinge blocks 5 and 6 in x
  std::vector<Vec3d> points = near_points;
  points.insert(points.end(), far_points.begin(), far_points.end());
  std::vector<double> labels = near_labels;
  labels.insert(labels.end(), far_labels.begin(), far_labels.end());
  BhmModel whole(p), halves(p);
  whole.update(points, labels);
  halves.update(near_points, near_labels);
  halves.update(far_points, far_labels);
  ASSERT_EQ(whole.block_count(), halves.block_count());
  ASSERT_GE(whole.block_count(), 2u);
  for (size_t b = 0; b < whole.block_count(); ++b) {
    const int64_t h = halves.find_block(whole.block_key(b));
    ASSERT_GE(h, 0);
    EXPECT_LT((whole.block_mean(b) - halves.block_mean(h)).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_LT((whole.block_cov(b) - halves.block_cov(h)).cwiseAbs().maxCoeff(), 1e-12);
  }
}

// Blocks that share points: the blocked model's coordinate ascent agrees with the full model where
// the data are (not to round-off: it drops the weights' correlations across blocks).
TEST(BhmModel, BlockedModelPredictsLikeOneFullBlock) {
  BhmParams blocked = tiny_params(), full = tiny_params();
  blocked.block_side = 4;  // the tiny problem's hinges in four blocks
  BhmModel a(blocked), b(full);
  std::vector<Vec3d> points;
  std::vector<double> labels;
  tiny_scan(5, 80, points, labels);
  a.update(points, labels);
  b.update(points, labels);
  EXPECT_GE(a.block_count(), 4u);
  EXPECT_EQ(b.block_count(), 1u);
  for (const Vec3d& x : points) {
    const double pa = BhmModel::probability(*a.logit(x)), pb = BhmModel::probability(*b.logit(x));
    EXPECT_NEAR(pa, pb, 0.05);
  }
}

// ---------------------------------------------------------------------------------------------
// Free beams: line integrals of the features, written out here by Simpson's rule.

std::vector<BhmBeam> tiny_beams(uint32_t seed, int n) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> at(1.3, 2.8);
  std::vector<BhmBeam> beams;
  for (int k = 0; k < n; ++k) beams.push_back({{1.0, 1.1, 0.25}, {at(rng), at(rng), 0.25}});
  return beams;
}

// int phi phi^T dt and int phi dt over one beam, from the definition: the supports within the
// features' reach of the segment, pairs of them at most twice the reach apart, the RBF itself
// (no cutoff) integrated by composite Simpson on 4000 intervals.
struct DenseBeam {
  Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(64, 64);
  Eigen::VectorXd g = Eigen::VectorXd::Zero(64);
  double length = 0;
};
DenseBeam dense_beam(const BhmBeam& beam, const BhmParams& p, double reach) {
  DenseBeam out;
  const double dx = beam.to.x - beam.from.x, dy = beam.to.y - beam.from.y;
  out.length = std::hypot(dx, dy);
  std::vector<bool> near(64, false);
  for (int u = 0; u < 64; ++u) {
    const double hx = 0.5 * (u % 8), hy = 0.5 * (u / 8);
    const double t = std::clamp(((hx - beam.from.x) * dx + (hy - beam.from.y) * dy) / (out.length * out.length), 0.0, 1.0);
    near[u] = std::hypot(beam.from.x + t * dx - hx, beam.from.y + t * dy - hy) <= reach;
  }
  const int n = 4000;
  for (int q = 0; q <= n; ++q) {
    const double w = (q == 0 || q == n ? 1.0 : (q % 2 ? 4.0 : 2.0)) * out.length / (3.0 * n);
    const double x = beam.from.x + dx * q / n, y = beam.from.y + dy * q / n;
    Eigen::VectorXd phi = Eigen::VectorXd::Zero(64);
    for (int u = 0; u < 64; ++u)
      if (near[u]) phi[u] = std::exp(-p.gamma * (std::pow(x - 0.5 * (u % 8), 2) + std::pow(y - 0.5 * (u / 8), 2)));
    out.g += w * phi;
    out.gram += w * phi * phi.transpose();
  }
  for (int u = 0; u < 64; ++u)
    for (int v = 0; v < 64; ++v)
      if (std::hypot(0.5 * (u % 8 - v % 8), 0.5 * (u / 8 - v / 8)) > 2 * reach) out.gram(u, v) = 0;
  return out;
}

// The data's part of the bound's precision and right-hand side for given xi (points', then beams').
void dense_data_terms(const Eigen::MatrixXd& phi, const std::vector<double>& labels, const std::vector<DenseBeam>& beams,
                      double density, const std::vector<double>& xi, Eigen::MatrixXd& precision, Eigen::VectorXd& rhs) {
  precision = Eigen::MatrixXd::Zero(64, 64);
  rhs = Eigen::VectorXd::Zero(64);
  const auto lambda = [](double x) { return std::tanh(x / 2) / (4 * x); };
  for (Eigen::Index r = 0; r < phi.rows(); ++r) {
    precision += 2 * lambda(xi[r]) * phi.row(r).transpose() * phi.row(r);
    rhs += (labels[r] - 0.5) * phi.row(r).transpose();
  }
  for (size_t k = 0; k < beams.size(); ++k) {
    precision += 2 * density * lambda(xi[phi.rows() + k]) * beams[k].gram;
    rhs -= 0.5 * density * beams[k].g;
  }
}

TEST(BhmModel, FreeBeamsEqualTheDenseFullCovarianceUpdateWithQuadrature) {
  const BhmParams p = tiny_params();
  const double density = 10.0;
  BhmModel model(p);
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(64);
  Eigen::MatrixXd cov = Eigen::MatrixXd::Identity(64, 64) * p.prior_var;
  for (uint32_t scan = 0; scan < 2; ++scan) {
    std::vector<Vec3d> points;
    std::vector<double> labels;
    tiny_scan(21 + scan, 20, points, labels);
    for (double& y : labels) y = 1.0;
    const std::vector<BhmBeam> beams = tiny_beams(31 + scan, 6);
    model.update(points, labels, beams, density);
    // The paper's EM with the beams' exact terms: xi_k^2 = tr(G_k (S + m m^T)) / length_k.
    const Eigen::MatrixXd phi = dense_features(points, p);
    std::vector<DenseBeam> dense;
    for (const BhmBeam& b : beams) dense.push_back(dense_beam(b, p, model.reach_m()));
    const Eigen::MatrixXd prior_precision = cov.inverse();
    const Eigen::VectorXd prior_rhs = prior_precision * mean;
    for (int it = 0; it < p.em_iterations; ++it) {
      const Eigen::MatrixXd second = cov + mean * mean.transpose();
      std::vector<double> xi;
      for (Eigen::Index r = 0; r < phi.rows(); ++r) xi.push_back(std::sqrt(phi.row(r) * second * phi.row(r).transpose()));
      for (const DenseBeam& b : dense) xi.push_back(std::sqrt((b.gram * second).trace() / b.length));
      Eigen::MatrixXd data_precision;
      Eigen::VectorXd data_rhs;
      dense_data_terms(phi, labels, dense, density, xi, data_precision, data_rhs);
      cov = (prior_precision + data_precision).inverse();
      mean = cov * (prior_rhs + data_rhs);
    }
    ASSERT_EQ(model.block_count(), 1u);
    EXPECT_LT((model.block_mean(0) - mean).cwiseAbs().maxCoeff(), 1e-9) << "scan " << scan;
    EXPECT_LT((model.block_cov(0) - cov).cwiseAbs().maxCoeff(), 1e-9) << "scan " << scan;
  }
  // The beams' free space: low probability along them, near the origin they share.
  EXPECT_LT(BhmModel::probability(*model.logit({1.2, 1.3, 0.25})), 0.3);
  EXPECT_LT(mean.minCoeff(), -0.5);
}

// Four blocks (block_side 4), xi fixed: one sweep of the colours is one block Gauss-Seidel step on
// the bound's precision, the cross-block terms of points and beams included.
TEST(BhmModel, FreeBeamsAcrossBlocksAreOneBlockGaussSeidelSweep) {
  BhmParams p = tiny_params();
  p.block_side = 4;
  p.threads = 2;
  const double density = 5.0;
  BhmModel model(p);
  std::vector<Vec3d> points;
  std::vector<double> labels;
  tiny_scan(41, 30, points, labels);
  const std::vector<BhmBeam> beams = tiny_beams(43, 8);
  std::vector<double> xi;
  for (size_t k = 0; k < points.size() + beams.size(); ++k) xi.push_back(0.2 + 0.07 * static_cast<double>(k % 13));
  model.update(points, labels, beams, density, &xi);

  std::vector<DenseBeam> dense;
  for (const BhmBeam& b : beams) dense.push_back(dense_beam(b, p, model.reach_m()));
  Eigen::MatrixXd precision;
  Eigen::VectorXd rhs;
  dense_data_terms(dense_features(points, p), labels, dense, density, xi, precision, rhs);
  precision += Eigen::MatrixXd::Identity(64, 64) / p.prior_var;
  // Column u of the 8 x 8 hinges is in block (i / 4, j / 4); colour = block x + 2 block y.
  const auto in_block = [](int u, int bx, int by) { return (u % 8) / 4 == bx && (u / 8) / 4 == by; };
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(64);
  std::vector<Eigen::MatrixXd> covs(4);
  for (int colour = 0; colour < 4; ++colour) {
    const int bx = colour & 1, by = colour >> 1;
    std::vector<int> ids;
    for (int u = 0; u < 64; ++u)
      if (in_block(u, bx, by)) ids.push_back(u);
    Eigen::MatrixXd pbb(16, 16);
    Eigen::VectorXd r(16);
    for (int a = 0; a < 16; ++a) {
      r[a] = rhs[ids[a]];
      for (int u = 0; u < 64; ++u)
        if (!in_block(u, bx, by)) r[a] -= precision(ids[a], u) * mean[u];
      for (int b = 0; b < 16; ++b) pbb(a, b) = precision(ids[a], ids[b]);
    }
    covs[colour] = pbb.inverse();
    const Eigen::VectorXd m = covs[colour] * r;
    for (int a = 0; a < 16; ++a) mean[ids[a]] = m[a];
  }
  ASSERT_EQ(model.block_count(), 4u);
  for (int colour = 0; colour < 4; ++colour) {
    const int64_t b = model.find_block({colour & 1, colour >> 1, 0});
    ASSERT_GE(b, 0);
    std::vector<int> ids;
    for (int u = 0; u < 64; ++u)
      if (in_block(u, colour & 1, colour >> 1)) ids.push_back(u);
    for (int a = 0; a < 16; ++a) {
      // Local support a of block (bx, by) is hinge (4 bx + a % 4, 4 by + a / 4): ids is in that order.
      EXPECT_NEAR(model.block_mean(b)[a], mean[ids[a]], 1e-9) << "block colour " << colour;
      for (int c = 0; c < 16; ++c) EXPECT_NEAR(model.block_cov(b)(a, c), covs[colour](a, c), 1e-9);
    }
  }
}

TEST(BhmModel, FreeBeamsAreRefusedIn3D) {
  BhmParams p = tiny_params();
  p.dims = 3;
  p.block_side = 4;
  BhmModel model(p);
  EXPECT_THROW(model.update({}, {}, tiny_beams(1, 2), 10.0), std::invalid_argument);
}

TEST(BhmModel, ProbabilitiesStayInsideZeroOneAndVarianceShrinksWithData) {
  BhmParams p = tiny_params();
  p.block_side = 4;
  BhmModel model(p);
  const Vec3d query{1.75, 1.75, 0.25};
  EXPECT_FALSE(model.logit(query).has_value());  // no block touched yet
  double last_variance = p.prior_var;
  for (int scan = 0; scan < 25; ++scan) {
    std::vector<Vec3d> points;
    std::vector<double> labels;
    tiny_scan(100 + scan, 30, points, labels);
    for (double& y : labels) y = 1.0;  // overwhelming evidence of occupancy
    model.update(points, labels);
    const std::optional<BhmLogit> a = model.logit(query);
    ASSERT_TRUE(a.has_value());
    EXPECT_LT(a->variance, last_variance) << "scan " << scan;
    EXPECT_GT(a->variance, 0.0);
    last_variance = a->variance;
    const double prob = BhmModel::probability(*a);
    EXPECT_GT(prob, 0.5);
    EXPECT_LT(prob, 1.0);
  }
  for (double x = -1; x <= 5; x += 0.37)
    for (double y = -1; y <= 5; y += 0.41)
      if (const std::optional<BhmLogit> a = model.logit({x, y, 0.25})) {
        const double prob = BhmModel::probability(*a);
        EXPECT_GT(prob, 0.0);
        EXPECT_LT(prob, 1.0);
        EXPECT_GE(a->variance, 0.0);
      }
}

// 2-D Simpson on n x n intervals of f over [-half, half]^2.
template <typename F>
double simpson_square(double half, int n, F&& f) {
  double sum = 0;
  const double step = 2 * half / n;
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j) {
      const double wi = (i == 0 || i == n) ? 1 : (i % 2 ? 4 : 2), wj = (j == 0 || j == n) ? 1 : (j % 2 ? 4 : 2);
      sum += wi * wj * f(-half + i * step, -half + j * step);
    }
  return sum * step * step / 9;
}

// Regionalised supports: the feature is the RBF averaged over the support (a uniform square, a
// Gaussian), and features() keeps every hinge whose feature reaches the cutoff, no other.
TEST(BhmModel, SupportFeaturesAreTheRbfAveragedOverTheSupport) {
  const Vec3d hinge{1.0, 1.5, 0.25};
  const std::vector<Vec3d> xs = {{1.0, 1.5, 0.25}, {1.13, 1.41, 0.25}, {1.3, 1.9, 0.25}, {0.55, 1.2, 0.25}};
  BhmParams rect = tiny_params();
  rect.support_side = 0.4;
  const BhmModel rect_model(rect);
  BhmParams gauss = tiny_params();
  gauss.support_var = 0.02;
  const BhmModel gauss_model(gauss);
  for (const Vec3d& x : xs) {
    const auto rbf = [&](double sx, double sy) {
      return std::exp(-rect.gamma * (std::pow(x.x - hinge.x - sx, 2) + std::pow(x.y - hinge.y - sy, 2)));
    };
    EXPECT_NEAR(rect_model.feature(x, hinge), simpson_square(0.2, 400, rbf) / (0.4 * 0.4), 1e-10);
    const double s = gauss.support_var, half = 8 * std::sqrt(s);
    const double expected = simpson_square(half, 800, [&](double sx, double sy) {
      return rbf(sx, sy) * std::exp(-(sx * sx + sy * sy) / (2 * s)) / (2 * M_PI * s);
    });
    EXPECT_NEAR(gauss_model.feature(x, hinge), expected, 1e-9);
  }
  for (const BhmModel* model : {&rect_model, &gauss_model}) {
    std::vector<BhmModel::Feature> f;
    const Vec3d x{1.62, 2.07, 0.25};
    model->features(x, f);
    size_t expected = 0;
    for (int i = -10; i < 20; ++i)
      for (int j = -10; j < 20; ++j) expected += model->feature(x, {0.5 * i, 0.5 * j, 0.25}) >= kFeatureCutoff;
    EXPECT_EQ(f.size(), expected);
    for (const BhmModel::Feature& feature : f) {
      EXPECT_GE(feature.value, kFeatureCutoff);
      EXPECT_DOUBLE_EQ(feature.value, model->feature(x, feature.hinge));
    }
  }
  BhmParams both = rect;
  both.support_var = 0.02;
  EXPECT_THROW(BhmModel{both}, std::invalid_argument);
  EXPECT_THROW(BhmModel(rect).update({}, {}, tiny_beams(1, 1), 10.0), std::invalid_argument);
}

// The paper's eq. 13 prints the Gaussian support's factor as |G^-1 S + 2I|^(-1/2), which is
// 2^(-d/2) for S = 0 where the support is a point and the factor must be 1: the correct
// |I + 2 G^-1 S|^(-1/2) (with G = I / gamma, (1 + 2 gamma s)^(-d/2)) is used.
TEST(BhmModel, GaussianSupportFactorIsTheCorrectedDeterminantOfEq13) {
  const Vec3d hinge{1.0, 1.5, 0.25};
  BhmParams point = tiny_params();
  point.support_var = 1e-12;
  EXPECT_NEAR(BhmModel(point).feature(hinge, hinge), 1.0, 1e-9);  // not 2^(-1), the misprint's
  BhmParams spread = tiny_params();
  spread.support_var = 0.05;
  const double corrected = 1 / (1 + 2 * spread.gamma * spread.support_var);  // d = 2
  const double misprint = 1 / (spread.gamma * spread.support_var + 2);
  EXPECT_NEAR(BhmModel(spread).feature(hinge, hinge), corrected, 1e-12);
  EXPECT_GT(std::abs(corrected - misprint), 0.1);
}

TEST(BhmModel, RefusesBadParameters) {
  BhmParams p = tiny_params();
  p.block_side = 65;  // 4225 supports per block
  EXPECT_THROW(BhmModel{p}, std::invalid_argument);
  p = tiny_params();
  p.gamma = 0;
  EXPECT_THROW(BhmModel{p}, std::invalid_argument);
  // Infinite values passed the "> 0" checks; a prior variance of 1e-300 overflows its inverse.
  for (double BhmParams::*field : {&BhmParams::spacing_m, &BhmParams::gamma, &BhmParams::prior_var,
                                   &BhmParams::support_var, &BhmParams::support_side}) {
    p = tiny_params();
    p.*field = INFINITY;
    EXPECT_THROW(BhmModel{p}, std::invalid_argument);
  }
  p = tiny_params();
  p.prior_var = 1e-300;
  EXPECT_THROW(BhmModel{p}, std::invalid_argument);
  p.prior_var = kMinBhmPriorVar;
  EXPECT_NO_THROW(BhmModel{p});
  // A spacing far below the reach (1.07 m): 4.61e8 hinges within reach of each point.
  p = tiny_params();
  p.spacing_m = 1e-4;
  try {
    BhmModel{p};
    ADD_FAILURE() << "spacing 1e-4 taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("bhm-spacing 0.0001 m puts 4.61e+08 hinges within reach", 0), 0u) << e.what();
  }
  p.spacing_m = 0.01;  // 4.6e4 hinges: taken
  EXPECT_NO_THROW(BhmModel{p});
}

// update_bytes counts the distinct blocks the points reach (the blocks of the hinge boxes within
// reach) without listing them: equal to the set of them written out; after an update of an empty
// model, the new blocks' mean, covariance and precision are no longer counted.
TEST(BhmModel, UpdateBytesCountsTheDistinctBlocksReached) {
  BhmParams p = tiny_params();
  p.block_side = 2;
  const auto reference = [&](const BhmModel& model, const std::vector<Vec3d>& points) {
    std::set<std::pair<int32_t, int32_t>> blocks;
    for (const Vec3d& x : points) {
      const int32_t lo_x = floor_div(int32_t(std::ceil((x.x - model.reach_m()) / p.spacing_m)), p.block_side);
      const int32_t hi_x = floor_div(int32_t(std::floor((x.x + model.reach_m()) / p.spacing_m)), p.block_side);
      const int32_t lo_y = floor_div(int32_t(std::ceil((x.y - model.reach_m()) / p.spacing_m)), p.block_side);
      const int32_t hi_y = floor_div(int32_t(std::floor((x.y + model.reach_m()) / p.spacing_m)), p.block_side);
      for (int32_t j = lo_y; j <= hi_y; ++j)
        for (int32_t i = lo_x; i <= hi_x; ++i) blocks.insert({i, j});
    }
    return blocks.size();
  };
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> at(-3.0, 6.0);
  std::vector<Vec3d> points;
  std::vector<double> labels;
  for (int k = 0; k < 300; ++k) {
    points.push_back({at(rng), at(rng), 0.25});
    labels.push_back(k % 3 == 0 ? 1.0 : 0.0);
  }
  BhmModel model(p);
  size_t reached = 0;
  const double before = model.update_bytes(points, {}, &reached);
  EXPECT_EQ(reached, reference(model, points));
  EXPECT_GT(reached, 20u);
  const BhmUpdateStats stats = model.update(points, labels);
  EXPECT_LE(stats.blocks, reached);
  size_t again = 0;
  const double after = model.update_bytes(points, {}, &again);
  EXPECT_EQ(again, reached);
  const double m = model.supports_per_block();
  EXPECT_DOUBLE_EQ(before - after, double(model.block_count()) * (2 * m * m + m) * 8);
  // Points 1e5 m apart: a bounding box of 1e10 blocks, too many to mark; the bound (the rows,
  // here disjoint) is then the count.
  const std::vector<Vec3d> far{{0.3, 0.3, 0.25}, {1e5, 1e5, 0.25}};
  EXPECT_EQ((model.update_bytes(far, {}, &reached), reached), reference(model, far));
}

// The evidence lower bound written out from its definition, dense, one full covariance:
// sum_n E_q[(y_n - 1/2) a_n + log sigma(xi_n) - xi_n / 2 - lambda(xi_n) (a_n^2 - xi_n^2)]
// - KL(N(m, S) || N(m0, S0)), xi_n^2 = phi_n^T (S + m m^T) phi_n, determinants by Eigen's LU.
double dense_elbo(const Eigen::MatrixXd& phi, const std::vector<double>& labels, const Eigen::VectorXd& mean,
                  const Eigen::MatrixXd& cov, const Eigen::VectorXd& prior_mean, const Eigen::MatrixXd& prior_cov) {
  double bound = 0;
  const Eigen::MatrixXd second_moment = cov + mean * mean.transpose();
  for (Eigen::Index r = 0; r < phi.rows(); ++r) {
    const double a = phi.row(r).dot(mean);
    const double a2 = phi.row(r) * second_moment * phi.row(r).transpose();
    const double xi = std::sqrt(a2);
    const double lambda = std::tanh(xi / 2) / (4 * xi);
    bound += (labels[r] - 0.5) * a + std::log(1 / (1 + std::exp(-xi))) - xi / 2 - lambda * (a2 - xi * xi);
  }
  const Eigen::MatrixXd prior_precision = prior_cov.inverse();
  const Eigen::VectorXd d = mean - prior_mean;
  const double kl = 0.5 * ((prior_precision * cov).trace() + d.dot(prior_precision * d) - double(mean.size()) +
                           std::log(prior_cov.determinant()) - std::log(cov.determinant()));
  return bound - kl;
}

TEST(BhmModel, ElboEqualsTheDenseDefinition) {
  BhmParams p = tiny_params();
  p.elbo = true;
  BhmModel model(p);
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(64);
  Eigen::MatrixXd cov = Eigen::MatrixXd::Identity(64, 64) * p.prior_var;
  for (uint32_t scan = 0; scan < 2; ++scan) {  // the second scan's prior is the first's posterior
    std::vector<Vec3d> points;
    std::vector<double> labels;
    tiny_scan(21 + scan, 50, points, labels);
    const Eigen::VectorXd prior_mean = mean;
    const Eigen::MatrixXd prior_cov = cov;
    const Eigen::MatrixXd phi = dense_features(points, p);
    const double elbo = model.update(points, labels).elbo;
    dense_update(phi, labels, p.em_iterations, mean, cov);
    const double expected = dense_elbo(phi, labels, mean, cov, prior_mean, prior_cov);
    EXPECT_NEAR(elbo, expected, 1e-9 * std::max(1.0, std::abs(expected))) << "scan " << scan;
    EXPECT_LT(elbo, 0.0);  // a bound on the log of a probability
  }
  // Off by default: nothing computed.
  BhmModel plain(tiny_params());
  std::vector<Vec3d> points;
  std::vector<double> labels;
  tiny_scan(21, 50, points, labels);
  EXPECT_EQ(plain.update(points, labels).elbo, 0.0);
}

// The bias (the paper's phi_0 = 1) as its own factor of q: with xi fixed, one update is one block
// Gauss-Seidel sweep on the dense full-covariance system with the bias column, the block first
// (against the bias's prior mean), then the bias (against the block's new mean); each factor's
// covariance is the inverse of its diagonal block of the dense precision.
TEST(BhmModel, BiasUpdateIsABlockGaussSeidelSweepOfTheDenseSystemWithTheBias) {
  BhmParams p = tiny_params();
  p.bias = true;
  p.prior_var = kPaperBhmPriorVar;
  BhmModel model(p);
  std::vector<Vec3d> points;
  std::vector<double> labels;
  tiny_scan(5, 60, points, labels);
  std::vector<double> xi(points.size());
  for (size_t k = 0; k < xi.size(); ++k) xi[k] = 0.2 + 0.07 * static_cast<double>(k % 13);
  model.update(points, labels, &xi);
  // Dense: column 0 the bias, then the 64 hinges.
  const Eigen::Index n = static_cast<Eigen::Index>(points.size());
  Eigen::MatrixXd phi(n, 65);
  phi.col(0).setOnes();
  phi.rightCols(64) = dense_features(points, p);
  Eigen::VectorXd lambda(n), y_half(n);
  for (Eigen::Index r = 0; r < n; ++r) {
    lambda[r] = std::tanh(xi[r] / 2) / (4 * xi[r]);
    y_half[r] = labels[r] - 0.5;
  }
  const Eigen::MatrixXd precision = Eigen::MatrixXd::Identity(65, 65) / p.prior_var +
                                    2 * phi.transpose() * lambda.asDiagonal() * phi;
  const Eigen::VectorXd rhs = phi.transpose() * y_half;  // the prior mean is 0
  const Eigen::MatrixXd p_bb = precision.bottomRightCorner(64, 64);
  const Eigen::VectorXd block_mean = p_bb.ldlt().solve(rhs.tail(64));  // against the bias's prior mean 0
  const double bias_mean = (rhs[0] - precision.row(0).tail(64).dot(block_mean)) / precision(0, 0);
  ASSERT_EQ(model.block_count(), 1u);
  EXPECT_LT((model.block_mean(0) - block_mean).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((model.block_cov(0) - p_bb.inverse()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_NEAR(model.bias_mean(), bias_mean, 1e-9);
  EXPECT_NEAR(model.bias_variance(), 1.0 / precision(0, 0), 1e-12);
  EXPECT_GT(std::abs(bias_mean), 1e-4);  // the labels moved it (the block, solved first, takes most)
  EXPECT_LT(model.bias_variance(), 0.1);
  // Predictions add the bias's mean and variance.
  const Vec3d q{1.7, 1.8, 0.25};
  const Eigen::VectorXd f = dense_features({q}, p).row(0).transpose();
  const std::optional<BhmLogit> a = model.logit(q);
  ASSERT_TRUE(a.has_value());
  EXPECT_NEAR(a->mean, f.dot(block_mean) + bias_mean, 1e-9);
  EXPECT_NEAR(a->variance, f.dot(p_bb.inverse() * f) + 1.0 / precision(0, 0), 1e-9);
}

// EM with the bias factor against the paper's exact model, dense, one full covariance over the
// bias and every hinge (xi from it): the factorisation drops the bias's correlation with the
// weights, so the two agree to a tolerance, not round-off. The ELBO is the dense definition's at
// the factorised q (the bias's KL counted).
TEST(BhmModel, BiasFactorPredictsLikeTheDenseFullCovarianceModelWithTheBias) {
  BhmParams p = tiny_params();
  p.bias = true;
  p.prior_var = kPaperBhmPriorVar;
  p.em_iterations = 8;
  p.elbo = true;
  BhmModel model(p);
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(65);
  Eigen::MatrixXd cov = Eigen::MatrixXd::Identity(65, 65) * p.prior_var;
  const std::vector<Vec3d> queries = {{1.5, 1.6, 0.25}, {2.0, 1.4, 0.25}, {1.8, 2.1, 0.25}, {1.4, 2.0, 0.25}};
  double worst = 0;
  for (uint32_t scan = 0; scan < 3; ++scan) {
    std::vector<Vec3d> points;
    std::vector<double> labels;
    tiny_scan(31 + scan, 60, points, labels);
    Eigen::MatrixXd phi(static_cast<Eigen::Index>(points.size()), 65);
    phi.col(0).setOnes();
    phi.rightCols(64) = dense_features(points, p);
    const auto factorised = [&](Eigen::VectorXd& m, Eigen::MatrixXd& c) {  // q as one dense Gaussian
      m.resize(65);
      c = Eigen::MatrixXd::Zero(65, 65);
      m[0] = model.bias_mean();
      c(0, 0) = model.bias_variance();
      if (model.block_count() == 0) {
        m.tail(64).setZero();
        c.bottomRightCorner(64, 64) = Eigen::MatrixXd::Identity(64, 64) * p.prior_var;
        return;
      }
      m.tail(64) = model.block_mean(0);
      c.bottomRightCorner(64, 64) = model.block_cov(0);
    };
    Eigen::VectorXd prior_mean, q_mean;
    Eigen::MatrixXd prior_cov, q_cov;
    factorised(prior_mean, prior_cov);
    const double elbo = model.update(points, labels).elbo;
    factorised(q_mean, q_cov);
    const double expected = dense_elbo(phi, labels, q_mean, q_cov, prior_mean, prior_cov);
    EXPECT_NEAR(elbo, expected, 1e-9 * std::max(1.0, std::abs(expected))) << "scan " << scan;
    dense_update(phi, labels, p.em_iterations, mean, cov);
    Eigen::MatrixXd fq(static_cast<Eigen::Index>(queries.size()), 65);
    fq.col(0).setOnes();
    fq.rightCols(64) = dense_features(queries, p);
    for (size_t k = 0; k < queries.size(); ++k) {
      const Eigen::VectorXd f = fq.row(static_cast<Eigen::Index>(k)).transpose();
      const double exact = BhmModel::probability({f.dot(mean), f.dot(cov * f)});
      worst = std::max(worst, std::abs(BhmModel::probability(*model.logit(queries[k])) - exact));
    }
  }
  std::printf("bias factor against the dense model with the bias: largest |p - p_dense| %.4f\n", worst);
  EXPECT_LT(worst, 0.05);
}

// Labels drawn from a Bayesian Hilbert map with a known gamma (weights from the prior, on the
// same hinges): the evidence should prefer that gamma's neighbourhood, and the search keeps the
// model of the candidate whose summed bound is largest.
TEST(BhmGammaSearch, ChoosesTheGammaTheDataCameFrom) {
  BhmParams p;
  p.spacing_m = 0.25;
  p.prior_var = 4.0;
  p.block_side = 8;
  p.em_iterations = 3;
  p.threads = 2;
  const std::vector<double> candidates = bhm_gamma_candidates(p);
  ASSERT_EQ(candidates.size(), 13u);  // 20 m^-2 times 2^(k/2), every one reaching within a 2 m block
  EXPECT_NEAR(candidates[6], 20.0, 1e-12);
  for (const double true_gamma : {candidates[4], candidates[8]}) {  // 10 and 40 m^-2
    BhmParams truth = p;
    truth.gamma = true_gamma;
    const BhmModel generator(truth);
    std::mt19937 rng(5);
    std::normal_distribution<double> weight(0.0, std::sqrt(p.prior_var));
    std::map<std::pair<int, int>, double> w;  // hinge (i, j) -> its weight
    std::uniform_real_distribution<double> at(0.5, 4.5), unit(0.0, 1.0);
    BhmGammaSearch search(p);
    std::vector<std::vector<Vec3d>> kept_points;
    std::vector<std::vector<double>> kept_labels;
    for (int scan = 0; scan < 2; ++scan) {
      std::vector<Vec3d> points;
      std::vector<double> labels;
      std::vector<BhmModel::Feature> f;
      for (int n = 0; n < 3000; ++n) {
        const Vec3d x{at(rng), at(rng), 0.0};
        generator.features(x, f);
        double a = 0;
        for (const BhmModel::Feature& feature : f) {
          const std::pair<int, int> key{static_cast<int>(std::lround(feature.hinge.x / p.spacing_m)),
                                        static_cast<int>(std::lround(feature.hinge.y / p.spacing_m))};
          auto it = w.find(key);
          if (it == w.end()) it = w.emplace(key, weight(rng)).first;
          a += feature.value * it->second;
        }
        points.push_back(x);
        labels.push_back(unit(rng) < 1 / (1 + std::exp(-a)) ? 1.0 : 0.0);
      }
      kept_points.push_back(points);
      kept_labels.push_back(labels);
      search.add_scan(points, labels, {}, 0.0);
    }
    BhmUpdateStats settled;
    const BhmModel model = search.choose(settled);
    const size_t best = search.best();
    for (const BhmGammaSearch::Candidate& c : search.candidates()) {
      std::printf("true gamma %.4g: candidate %.4g ELBO %.3f%s\n", true_gamma, c.gamma, c.elbo,
                  &c == &search.candidates()[best] ? " (chosen)" : "");
      EXPECT_GE(search.candidates()[best].elbo, c.elbo);
    }
    const double chosen = search.candidates()[best].gamma;
    EXPECT_LE(chosen, true_gamma * 1.5) << "true gamma " << true_gamma;  // within one step of sqrt(2)
    EXPECT_GE(chosen, true_gamma / 1.5) << "true gamma " << true_gamma;
    // The model that goes on has the chosen gamma and has learned both scans, as a fresh one would.
    EXPECT_EQ(model.params().gamma, chosen);
    EXPECT_FALSE(model.params().elbo);
    BhmParams fresh_params = p;
    fresh_params.gamma = chosen;
    BhmModel fresh(fresh_params);
    BhmUpdateStats fresh_stats;
    for (size_t k = 0; k < kept_points.size(); ++k) {
      const BhmUpdateStats stats = fresh.update(kept_points[k], kept_labels[k]);
      fresh_stats.rows += stats.rows;
      fresh_stats.blocks += stats.blocks;
    }
    // Its updates are counted: the map's counts include the evidence scans.
    EXPECT_EQ(settled.rows, fresh_stats.rows);
    EXPECT_EQ(settled.blocks, fresh_stats.blocks);
    ASSERT_EQ(model.block_count(), fresh.block_count());
    EXPECT_GT(model.block_count(), 4u);
    for (size_t b = 0; b < fresh.block_count(); ++b) EXPECT_TRUE(model.block_mean(b) == fresh.block_mean(b)) << b;
  }
}

// ---------------------------------------------------------------------------------------------
// The method

Scan planar_scan(float z, float offset) {
  Scan scan;
  scan.pose.position = {0.0f, 0.0f, z};
  for (int k = 0; k < 720; ++k) {  // a hit every 2.6 cm on the wall
    const double angle = 2 * M_PI * k / 720;
    scan.points.push_back({static_cast<float>(3.0 * std::cos(angle)) + offset,
                           static_cast<float>(3.0 * std::sin(angle)), z});
  }
  return scan;
}

std::unique_ptr<MappingMethod> bhm_method(double resolution_m, int threads, const MethodParams& method = {}) {
  BuildParams params;
  params.grid.resolution_m = resolution_m;
  BackendOptions backend;
  backend.backend = "cpu";
  backend.threads = threads;
  return make_method("bhm", params, method, backend);
}

// --bhm-mode paper: the paper's prior variance, bias and Intel gamma for every one not given
// (before or after the mode), back to the defaults with --bhm-mode default.
TEST(BhmMethod, PaperModeSetsThePapersValuesWhereNotGiven) {
  MethodParams m;
  EXPECT_EQ(m.number("bhm-gamma"), 20.0);
  EXPECT_EQ(m.number("bhm-prior-var"), 1.0);
  EXPECT_EQ(m.choice("bhm-bias"), "none");
  m.set("bhm-mode", "paper");
  EXPECT_DOUBLE_EQ(m.number("bhm-gamma"), 1.0 / 0.15);
  EXPECT_EQ(m.number("bhm-prior-var"), 1e4);
  EXPECT_EQ(m.choice("bhm-bias"), "global");
  EXPECT_EQ(m.number("bhm-spacing"), 0.25);  // the paper gives no Intel spacing
  m.set("bhm-gamma", 0.0);  // given after the mode: kept
  EXPECT_EQ(m.number("bhm-gamma"), 0.0);
  MethodParams given_first;
  given_first.set("bhm-prior-var", 3.0);
  given_first.set("bhm-mode", "paper");
  EXPECT_EQ(given_first.number("bhm-prior-var"), 3.0);
  EXPECT_EQ(given_first.choice("bhm-bias"), "global");
  given_first.set("bhm-mode", "default");
  EXPECT_EQ(given_first.number("bhm-prior-var"), 3.0);
  EXPECT_EQ(given_first.choice("bhm-bias"), "none");
  EXPECT_EQ(given_first.number("bhm-gamma"), 20.0);
  // A bias with free beams is refused in one line.
  MethodParams beams;
  beams.set("bhm-mode", "paper");
  beams.set("bhm-free", "beams");
  try {
    beams.validate();
    ADD_FAILURE() << "a bias with free beams was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--bhm-bias global (--bhm-mode paper's) needs --bhm-free points: a bias with "
                                         "free beams is not implemented; give --bhm-bias none or --bhm-free points"),
              std::string::npos)
        << e.what();
  }
}

TEST(BhmMethod, PlanarScansMakeA2DMapAndMixingIsRefused) {
  std::unique_ptr<MappingMethod> method = bhm_method(0.1, 1);
  method->insert(planar_scan(0.4f, 0.0f));
  method->insert(planar_scan(0.4f, 0.2f));
  // A wall at 3 m, free space inside; the 2-D map answers at any height.
  const std::optional<CellEstimate> wall = method->estimate(3.05, 0.05, 0.4);
  const std::optional<CellEstimate> inside = method->estimate(1.5, 0.05, 7.0);
  ASSERT_TRUE(wall && inside);
  EXPECT_GT(wall->occupancy, 0.5);
  EXPECT_LT(inside->occupancy, 0.5);
  ASSERT_TRUE(wall->logit_mean && wall->variance);
  EXPECT_GT(*wall->logit_mean, 0.0);
  EXPECT_GT(*wall->variance, 0.0);
  EXPECT_GT(method->known_cells(), 0u);
  EXPECT_THROW(method->check_output("m.bgk"), InputError);

  Scan tilted = planar_scan(0.4f, 0.0f);
  tilted.points[3].z = 0.5f;
  try {
    method->insert(tilted);
    FAIL() << "a 3-D scan after planar ones was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("cannot be mixed"), std::string::npos) << e.what();
  }
  try {
    method->insert(planar_scan(0.9f, 0.0f));
    FAIL() << "a planar scan at another height was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("z = 0.9"), std::string::npos) << e.what();
  }
}

TEST(BhmMethod, ThreeDScansMakeA3DMap) {
  std::unique_ptr<MappingMethod> method = bhm_method(0.2, 2);
  const std::vector<Scan> scans = testing::random_scans(4, 2, 150, 2.0f);
  for (const Scan& scan : scans) method->insert(scan);
  const Vec3f& hit = scans[0].points[0];
  const std::optional<CellEstimate> e = method->estimate(hit.x, hit.y, hit.z);
  ASSERT_TRUE(e.has_value());
  EXPECT_GT(e->occupancy, 0.0);
  EXPECT_LT(e->occupancy, 1.0);
  EXPECT_GT(method->known_cells(), 0u);
  EXPECT_THROW(method->insert(planar_scan(0.0f, 0.0f)), std::invalid_argument);
}

TEST(BhmMethod, FreeBeamsMapPlanarScansAndAreRefusedFor3D) {
  MethodParams beams;
  beams.set("bhm-free", "beams");
  std::unique_ptr<MappingMethod> method = bhm_method(0.1, 2, beams);
  method->insert(planar_scan(0.4f, 0.0f));
  method->insert(planar_scan(0.4f, 0.2f));
  // The wall at 3 m (the cell centred 3.15 m), free space inside. The free evidence runs on to
  // --end-margin before the hit, where sampled points stop up to one spacing earlier.
  const std::optional<CellEstimate> wall = method->estimate(3.15, 0.05, 0.4);
  const std::optional<CellEstimate> before = method->estimate(2.85, 0.05, 0.4);
  const std::optional<CellEstimate> inside = method->estimate(1.5, 0.05, 0.4);
  ASSERT_TRUE(wall && before && inside);
  EXPECT_GT(wall->occupancy, 0.6);
  EXPECT_LT(before->occupancy, 0.1);
  EXPECT_LT(inside->occupancy, 0.1);

  method = bhm_method(0.2, 1, beams);
  try {
    method->insert(testing::random_scans(4, 1, 150, 2.0f)[0]);
    FAIL() << "a 3-D scan was accepted with free beams";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--bhm-free beams"), std::string::npos) << e.what();
  }
}

// ---------------------------------------------------------------------------------------------
// The command: simulate planar scans, build with bhm (.ot of its probabilities and .bt, the report),
// score the map.

testing::CommandResult run(const std::string& args) {
  return testing::run_command(std::string(BGKMAP_CLI) + " " + args);
}

TEST(BhmCli, BuildsSimulatedPlanarScansAndEvalScoresThem) {
  const std::filesystem::path dir = testing::make_temp_dir("bhm_cli");
  const std::string d = dir.string();
  testing::CommandResult r = run("simulate structured -o " + d + "/sim --sensor planar --scans 4 -q");
  ASSERT_EQ(r.status, 0) << r.output;
  r = run("build -q --method bhm " + d + "/sim/scans --ot-values mean -o " + d + "/m.ot -o " + d + "/m.bt --report " + d +
          "/r.json --threads 2 --free-resolution 0.3 --bhm-spacing 0.6 --bhm-gamma 4 --bhm-em-iterations 2");
  ASSERT_EQ(r.status, 0) << r.output;
  std::ifstream in(dir / "r.json");
  const nlohmann::json report = nlohmann::json::parse(in);
  EXPECT_EQ(report["params"]["method"], "bhm");
  EXPECT_DOUBLE_EQ(report["params"]["bhm_spacing"].get<double>(), 0.6);
  EXPECT_DOUBLE_EQ(report["params"]["bhm_em_iterations"].get<double>(), 2.0);
  EXPECT_EQ(report["counts"]["scans"].get<int>(), 4);
  EXPECT_GT(report["counts"]["blocks_touched"].get<int>(), 0);
  EXPECT_GT(report["peak_rss_mb"].get<double>(), 0.0);
  EXPECT_TRUE(std::filesystem::exists(dir / "m.ot"));
  EXPECT_TRUE(std::filesystem::exists(dir / "m.bt"));
  r = run("eval " + d + "/m.ot --truth " + d + "/sim/truth.bt --json " + d + "/e.json");
  ASSERT_EQ(r.status, 0) << r.output;
  std::ifstream ein(dir / "e.json");
  const nlohmann::json scores = nlohmann::json::parse(ein);
  const std::string dumped = scores.dump();
  EXPECT_NE(dumped.find("auc"), std::string::npos) << dumped.substr(0, 400);
  // Free space as beams: the same scans, the flag in the report.
  r = run("build -q --method bhm " + d + "/sim/scans -o " + d + "/b.ot --report " + d +
          "/rb.json --threads 2 --free-resolution 0.3 --bhm-spacing 0.6 --bhm-gamma 4 --bhm-free beams");
  ASSERT_EQ(r.status, 0) << r.output;
  std::ifstream bin(dir / "rb.json");
  EXPECT_EQ(nlohmann::json::parse(bin)["params"]["bhm_free"], "beams");
  r = run("build -q --method bhm " + d + "/sim/scans -o " + d + "/c.ot --bhm-free rays");
  EXPECT_NE(r.status, 0);
  // gamma chosen by the evidence of the first two scans: the choice and the bounds in the report.
  r = run("build -q --method bhm " + d + "/sim/scans -o " + d + "/g.ot --report " + d +
          "/rg.json --threads 2 --free-resolution 0.3 --bhm-spacing 0.6 --bhm-gamma 0 --bhm-evidence-scans 2");
  ASSERT_EQ(r.status, 0) << r.output;
  std::ifstream gin(dir / "rg.json");
  const nlohmann::json chosen = nlohmann::json::parse(gin);
  const std::string device = chosen["backend"]["device"].get<std::string>();
  EXPECT_NE(device.find("chosen by the evidence of 2 scan(s)"), std::string::npos) << device;
  EXPECT_EQ(chosen["counts"]["scans"].get<int>(), 4);
  EXPECT_GT(chosen["counts"]["blocks_touched"].get<int>(), 0);
  r = run("build -q --method bhm " + d + "/sim/scans -o " + d + "/h.ot --bhm-gamma -1");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("bhm-gamma"), std::string::npos) << r.output;
  // .bgk is refused before any work.
  r = run("build -q --method bhm " + d + "/sim/scans -o " + d + "/m.bgk");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("m.bgk"), std::string::npos) << r.output;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap
