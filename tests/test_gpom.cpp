// --method gpom and wgpom against plain references: the Matern covariance, leave-one-out
// predictions against refitting without each point, the PLSC likelihood's gradient against finite
// differences and its fit against known parameters, the whole map against an exact dense GP per
// cell (every hit and beam in the local model), in double precision; wgpom's Gauss-Hermite rule,
// warp, warped likelihood and its gradient, learning, and unwarped predictions, each against a
// plain reference, and its map against the dense warped GP. The neural-network covariance against
// its formula, its Gram matrices' eigenvalues, and the same dense references.
#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "bgkmap/core/pose_covariance.hpp"
#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/methods/method.hpp"
#include "core/gauss_hermite.hpp"
#include "methods/gp/gp_hyperparameters.hpp"
#include "methods/gp/gp_regression.hpp"
#include "methods/gpom/gpom_method.hpp"
#include "methods/gp/plsc.hpp"
#include "methods/wgpom/warped_gp.hpp"
#include "support/dense_gp.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

using testing::cpu_backend;

// The neural-network covariance written out (Williams 1998): s2 (2/pi) asin(2 a~'S b~ /
// sqrt((1 + 2 a~'S a~)(1 + 2 b~'S b~))), a~ = (1, a), S = diag(s0^2, 1/l^2, 1/l^2, 1/l^2), s0^2 = 1.
double neural_network_formula(const Vec3d& a, const Vec3d& b, double ell, double s2) {
  const double s0_squared = 1.0;
  const auto form = [&](const Vec3d& u, const Vec3d& v) {  // u~^T S v~: the bias inputs 1 * s0^2 * 1, then u^T v / l^2
    return s0_squared + (u.x * v.x + u.y * v.y + u.z * v.z) / (ell * ell);
  };
  return s2 * 2 / M_PI * std::asin(2 * form(a, b) / std::sqrt((1 + 2 * form(a, a)) * (1 + 2 * form(b, b))));
}

// The references' covariance of two inputs: the formula above for nn, the kernel of the distance
// otherwise.
double reference_covariance(const Vec3d& a, const Vec3d& b, const GpHyperParams& hp) {
  if (hp.covariance == GpCovariance::kNeuralNetwork) return neural_network_formula(a, b, hp.ell_m, hp.signal_var);
  return gp_kernel(std::sqrt((a.x - b.x) * (a.x - b.x) + (a.y - b.y) * (a.y - b.y) + (a.z - b.z) * (a.z - b.z)), hp);
}

// The reference GP on inputs x: the covariance matrix and k* by reference_covariance, solved by
// testing::dense_gp (Gauss-Jordan on the full system, no Cholesky, no Eigen).
GpPrediction dense_gp(const std::vector<Vec3d>& x, const std::vector<double>& y, const Vec3d& q, const GpHyperParams& hp) {
  const size_t n = x.size();
  std::vector<std::vector<double>> k(n, std::vector<double>(n));
  std::vector<double> ks(n);
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = 0; j < n; ++j) k[i][j] = reference_covariance(x[i], x[j], hp) + (i == j ? hp.noise_std * hp.noise_std : 0);
    ks[i] = reference_covariance(x[i], q, hp);
  }
  return testing::dense_gp(k, ks, reference_covariance(q, q, hp), y);
}

TEST(GpomCovariance, MaternThreeHalvesIsItsFormula) {
  GpHyperParams hp;
  hp.covariance = GpCovariance::kMatern32;
  hp.ell_m = 0.7;
  hp.signal_var = 2.5;
  for (const double d : {0.0, 0.1, 0.7, 2.0}) {
    const double r = std::sqrt(3.0) * d / 0.7;
    EXPECT_NEAR(gp_kernel(d, hp), 2.5 * (1 + r) * std::exp(-r), 1e-14) << d;
  }
  EXPECT_GT(gp_kernel(5.0, hp), 0);  // no compact support, unlike the sparse kernel
}

TEST(GpomCovariance, NeuralNetworkIsItsFormula) {
  GpHyperParams hp;
  hp.covariance = GpCovariance::kNeuralNetwork;
  hp.ell_m = 0.7;
  hp.signal_var = 2.5;
  const std::vector<Vec3d> points{{0, 0, 0}, {0.3, -0.2, 0.1}, {-1.5, 0.4, 0}, {2.0, 2.0, -1.0}, {0.01, 0, 0}};
  for (const Vec3d& a : points)
    for (const Vec3d& b : points) {
      EXPECT_NEAR(gp_covariance(a, b, hp), neural_network_formula(a, b, 0.7, 2.5), 1e-14);
      EXPECT_EQ(gp_covariance(a, b, hp), gp_covariance(b, a, hp));
    }
  // At the origin: s2 (2/pi) asin(2/3); not stationary: the same offset elsewhere differs.
  EXPECT_NEAR(gp_covariance({0, 0, 0}, {0, 0, 0}, hp), 2.5 * 2 / M_PI * std::asin(2.0 / 3), 1e-14);
  EXPECT_GT(std::abs(gp_covariance({0, 0, 0}, {0.3, 0, 0}, hp) - gp_covariance({1, 0, 0}, {1.3, 0, 0}, hp)), 0.01);
  EXPECT_THROW(gp_kernel(0.1, hp), std::invalid_argument);  // not a function of the distance
  hp.covariance = GpCovariance::kMatern32;  // the stationary ones: the kernel of the distance
  EXPECT_EQ(gp_covariance({0.1, 0.2, 0.3}, {-0.4, 0.6, 0.3}, hp), gp_kernel(std::sqrt(0.25 + 0.16), hp));
}

TEST(GpomCovariance, NeuralNetworkGramMatricesArePositiveSemiDefinite) {
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> u(-3, 3);
  for (const double ell : {0.1, 0.5, 2.0}) {
    GpHyperParams hp;
    hp.covariance = GpCovariance::kNeuralNetwork;
    hp.ell_m = ell;
    hp.signal_var = 1.7;
    const int n = 80;
    std::vector<Vec3d> x(n);
    for (Vec3d& p : x) p = {u(rng), u(rng), u(rng)};
    x[1] = x[0];  // a repeated input: a singular Gram matrix
    Eigen::MatrixXd k(n, n);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) k(i, j) = gp_covariance(x[i], x[j], hp);
    const Eigen::VectorXd eigenvalues = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(k).eigenvalues();
    EXPECT_GE(eigenvalues.minCoeff(), -1e-12 * hp.signal_var) << ell;
    EXPECT_LT(eigenvalues.minCoeff(), 1e-9) << ell;  // the repeated input
  }
}

std::vector<Vec3d> random_points(std::mt19937& rng, int n, double extent) {
  std::uniform_real_distribution<double> u(0, extent);
  std::vector<Vec3d> out(n);
  for (Vec3d& p : out) p = {u(rng), u(rng), u(rng)};
  return out;
}

TEST(GpomLeaveOneOut, EqualsRefittingWithoutEachPoint) {
  std::mt19937 rng(3);
  for (const GpCovariance covariance : {GpCovariance::kMatern32, GpCovariance::kSparse, GpCovariance::kSquaredExponential,
                                       GpCovariance::kNeuralNetwork}) {
    GpHyperParams hp;
    hp.covariance = covariance;
    hp.ell_m = 0.8;
    hp.signal_var = 1.3;
    hp.noise_std = 0.2;
    const std::vector<Vec3d> x = random_points(rng, 25, 1.0);
    std::vector<double> y(x.size());
    for (size_t i = 0; i < y.size(); ++i) y[i] = (x[i].x + x[i].y > 1) ? 1.0 : -1.0;
    const std::vector<GpPrediction> loo = gp_leave_one_out(x, y, hp);
    for (size_t i = 0; i < x.size(); ++i) {
      std::vector<Vec3d> xi = x;
      std::vector<double> yi = y;
      xi.erase(xi.begin() + i);
      yi.erase(yi.begin() + i);
      const GpPrediction ref = dense_gp(xi, yi, x[i], hp);
      // R&W eq. 5.12's variance is that of the held-out label: the latent variance plus noise.
      EXPECT_NEAR(loo[i].mean, ref.mean, 1e-10) << i;
      EXPECT_NEAR(loo[i].variance, ref.variance + hp.noise_std * hp.noise_std, 1e-10) << i;
    }
  }
}

TEST(GpomRegression, GpPredictWithMaternAndNeuralNetworkEqualsTheDenseReference) {
  for (const GpCovariance covariance : {GpCovariance::kMatern32, GpCovariance::kNeuralNetwork}) {
    std::mt19937 rng(4);
    GpHyperParams hp;
    hp.covariance = covariance;
    hp.ell_m = 0.5;
    hp.signal_var = 1.0;
    hp.noise_std = 0.1;
    const std::vector<Vec3d> x = random_points(rng, 40, 2.0), q = random_points(rng, 10, 2.0);
    std::vector<double> y(x.size());
    for (size_t i = 0; i < y.size(); ++i) y[i] = i % 3 ? -1.0 : 1.0;
    const std::vector<GpPrediction> got = gp_predict(x, y, q, hp);
    for (size_t t = 0; t < q.size(); ++t) {
      const GpPrediction ref = dense_gp(x, y, q[t], hp);
      EXPECT_NEAR(got[t].mean, ref.mean, 1e-9) << t;
      EXPECT_NEAR(got[t].variance, ref.variance, 1e-9) << t;
    }
  }
}

std::vector<LooSample> synthetic_samples(double alpha, double beta, int n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> mean(-1.5, 1.5), variance(0.01, 0.5), u(0, 1);
  std::vector<LooSample> out(n);
  for (LooSample& s : out) {
    s.mean = mean(rng);
    s.variance = variance(rng);
    s.label = u(rng) < plsc_probability(s.mean, s.variance, {alpha, beta}) ? 1.0 : -1.0;
  }
  return out;
}

TEST(GpomPlsc, ProbabilityIsThePaperFormula) {
  const PlscParams plsc{2.0, -0.3};
  const double mean = 0.4, variance = 0.2;
  const double z = (2.0 * 0.4 - 0.3) / std::sqrt(1 + 4.0 * 0.2);
  EXPECT_NEAR(plsc_probability(mean, variance, plsc), 0.5 * (1 + std::erf(z / std::sqrt(2.0))), 1e-15);
}

TEST(GpomPlsc, GradientMatchesFiniteDifferences) {
  const std::vector<LooSample> samples = synthetic_samples(1.7, 0.2, 300, 5);
  for (const PlscParams at : {PlscParams{1.0, 0.0}, PlscParams{3.0, -0.5}, PlscParams{0.3, 0.8}}) {
    double da = 0, db = 0;
    plsc_log_likelihood(samples, at, &da, &db);
    const double h = 1e-6;
    const double fa = (plsc_log_likelihood(samples, {at.alpha + h, at.beta}) -
                       plsc_log_likelihood(samples, {at.alpha - h, at.beta})) / (2 * h);
    const double fb = (plsc_log_likelihood(samples, {at.alpha, at.beta + h}) -
                       plsc_log_likelihood(samples, {at.alpha, at.beta - h})) / (2 * h);
    EXPECT_NEAR(da, fa, 1e-5 * (1 + std::abs(fa)));
    EXPECT_NEAR(db, fb, 1e-5 * (1 + std::abs(fb)));
  }
}

TEST(GpomPlsc, FitIsTheMaximumAndRecoversTheGeneratingParameters) {
  const std::vector<LooSample> samples = synthetic_samples(2.0, 0.3, 20000, 6);
  const PlscParams fit = fit_plsc(samples);
  EXPECT_NEAR(fit.alpha, 2.0, 0.2);
  EXPECT_NEAR(fit.beta, 0.3, 0.06);
  double da = 0, db = 0;
  const double best = plsc_log_likelihood(samples, fit, &da, &db);
  EXPECT_LT(std::abs(da) / samples.size(), 1e-7);
  EXPECT_LT(std::abs(db) / samples.size(), 1e-7);
  for (const double step : {-0.01, 0.01}) {
    EXPECT_LT(plsc_log_likelihood(samples, {fit.alpha + step, fit.beta}), best);
    EXPECT_LT(plsc_log_likelihood(samples, {fit.alpha, fit.beta + step}), best);
  }
  EXPECT_EQ(fit_plsc({}, {1.5, 0.1}).alpha, 1.5);  // nothing to fit: the start
}

// A planar scan (z = 0) well inside one block of 32 x 32 x 32 cells: the local models hold every
// hit and beam (k = 30 >= both), so each cell is an exact GP on all hits and the nearest points
// of all free segments. The PLSC squashing is fitted as the method does it: leave-one-out
// predictions of the block's first evaluated cell and every 64th after it, cells in order.
// With a warp (wgpom given that warp): the dense GP models g(y), its latent prediction and the
// leave-one-out ones unwarped by unwarp_prediction (tested against a fine integral below).
// With the neural-network covariance the reference takes each cell's inputs relative to its query
// (the query at the origin), as gpom's local models do.
void expect_dense_gp_per_cell(const std::string& name, const TanhWarp* warp, const std::string& covariance = "matern") {
  const BuildParams params = testing::small_planar_params();
  MethodParams mp;
  mp.set("gp-length", 0.3);
  mp.set("gp-signal", 1.0);
  mp.set("gp-noise", 0.1);
  mp.set("gp-covariance", covariance);
  Scan scan;
  scan.pose.position = {1.62f, 1.55f, 0.0f};
  for (int i = 0; i < 12; ++i) {
    const double a = 0.5 * i, r = 0.4 + 0.05 * (i % 5);
    scan.points.push_back({static_cast<float>(1.62 + r * std::cos(a)), static_cast<float>(1.55 + r * std::sin(a)), 0.0f});
  }
  auto method = warp ? make_wgpom_method(params, mp, cpu_backend(), *warp) : make_method(name, params, mp, cpu_backend());
  ASSERT_EQ(method->name(), name);
  method->insert(scan);
  method->finish();
  const GaussHermite rule(20);
  const auto label_space = [&](const GpPrediction& latent) {
    return warp ? unwarp_prediction(latent.mean, latent.variance, *warp, rule) : latent;
  };

  ScanObservations obs;
  PreprocessCounts counts;
  preprocess_scan(scan, params.preprocess, obs, counts);
  ASSERT_EQ(obs.hits.size(), 12u);
  ASSERT_EQ(obs.free_ends.size(), 12u);
  GpHyperParams hp;
  hp.covariance = covariance == "nn" ? GpCovariance::kNeuralNetwork : GpCovariance::kMatern32;
  hp.ell_m = 0.3;
  hp.signal_var = 1.0;
  hp.noise_std = 0.1;
  const Vec3d o{obs.origin.x, obs.origin.y, obs.origin.z};
  std::vector<LooSample> pool;
  std::vector<std::pair<Vec3d, GpPrediction>> expected;
  int evaluated = 0;
  for (int cy = 0; cy < 32; ++cy)
    for (int cx = 0; cx < 32; ++cx) {
      const Vec3d q{(cx + 0.5) * 0.1, (cy + 0.5) * 0.1, 0.0};
      std::vector<Vec3d> x;
      std::vector<double> y;
      double nearest = INFINITY;
      for (const Vec3f& h : obs.hits) {
        x.push_back({h.x, h.y, h.z});
        y.push_back(1);
      }
      for (const Vec3f& e : obs.free_ends) {
        const Vec3d d{e.x - o.x, e.y - o.y, e.z - o.z};
        const double t = std::clamp(((q.x - o.x) * d.x + (q.y - o.y) * d.y) / (d.x * d.x + d.y * d.y), 0.0, 1.0);
        x.push_back({o.x + t * d.x, o.y + t * d.y, o.z + t * d.z});
        y.push_back(-1);
      }
      for (const Vec3d& p : x) nearest = std::min(nearest, std::hypot(p.x - q.x, p.y - q.y));
      const std::optional<CellEstimate> e = method->estimate(q.x, q.y, 0.0);
      if (nearest > 0.3 + 1e-9) {
        EXPECT_FALSE(e.has_value()) << cx << "," << cy;
        continue;
      }
      if (nearest > 0.3 - 1e-9) continue;  // on the reach boundary: float rounding decides
      ASSERT_TRUE(e.has_value()) << cx << "," << cy;
      std::vector<double> z = y;
      if (warp)
        for (double& label : z) label = warp->value(label);
      Vec3d query = q;
      if (hp.covariance == GpCovariance::kNeuralNetwork) {
        for (Vec3d& p : x) p = {p.x - q.x, p.y - q.y, p.z - q.z};
        query = {0, 0, 0};
      }
      const GpPrediction ref = label_space(dense_gp(x, z, query, hp));
      EXPECT_NEAR(*e->gp_mean, ref.mean, 1e-9) << cx << "," << cy;
      EXPECT_NEAR(*e->variance, ref.variance, 1e-9) << cx << "," << cy;
      expected.push_back({q, ref});
      if (evaluated++ % 64 == 0) {
        const std::vector<GpPrediction> loo = gp_leave_one_out(x, z, hp);
        for (size_t i = 0; i < loo.size(); ++i) {
          const GpPrediction held_out = label_space(loo[i]);
          pool.push_back({y[i], held_out.mean, held_out.variance});
        }
      }
    }
  ASSERT_GT(expected.size(), 100u);
  // The pools hold the same samples in another order (the method's local models list training
  // points nearest first), and the likelihood is flat at its maximum: alpha and beta agree to
  // about sqrt(machine epsilon), the probabilities to 1e-7.
  const PlscParams plsc = fit_plsc(pool);
  for (const auto& [q, ref] : expected)
    EXPECT_NEAR(*method->occupancy(q.x, q.y, 0.0), plsc_probability(ref.mean, ref.variance, plsc), 1e-7);
  EXPECT_EQ(method->known_cells(), static_cast<uint64_t>(evaluated));
  // 2-D: only the plane's layer is mapped.
  EXPECT_FALSE(method->estimate(1.62, 1.55, 0.15).has_value());
  // Occupied at a hit, free between the origin and the hits.
  EXPECT_GT(*method->occupancy(scan.points[0].x, scan.points[0].y, 0.0), 0.5);
  EXPECT_LT(*method->occupancy(1.65, 1.55, 0.0), 0.5);
  EXPECT_THROW(method->check_output("map.bgk"), InputError);
}

TEST(GpomMethod, EqualsTheDenseGpPerCellWithAllDataIn2D) { expect_dense_gp_per_cell("gpom", nullptr); }

TEST(GpomMethod, NeuralNetworkCovarianceEqualsTheDenseGpPerCellCentredAtTheQuery) {
  expect_dense_gp_per_cell("gpom", nullptr, "nn");
}

// A two-term warp, far from the identity, for the dense references.
TanhWarp two_term_warp() {
  TanhWarp warp;
  warp.d = 0.4;
  warp.a = {1.5, 0.7};
  warp.b = {2.0, 0.8};
  warp.c = {-0.9, 0.6};
  return warp;
}

TEST(WgpomMethod, EqualsTheDenseWarpedGpPerCellWithAllDataIn2D) {
  const TanhWarp warp = two_term_warp();
  expect_dense_gp_per_cell("wgpom", &warp);
}

// Pose uncertainty, the expected sub-map: two planar scans, the first certain, the second with
// a planar covariance (6 sigma points), every datum in every local model. The reference: per
// sigma point h, the dense GP (warped for wgpom) on scan 1 as is and scan 2 displaced by its h-th
// point; the cell's mean and variance those of the equal-weight mixture, from its raw moments
// (E[m^2] - E[m]^2, not the method's two-pass form). Known where every hypothesis has data within
// reach. Tolerance 1e-9 (double precision; the displaced points are the same floats).
void expect_dense_expected_submap(const std::string& name, const TanhWarp* warp) {
  const BuildParams params = testing::small_planar_params();
  const MethodParams mp = testing::dense_reference_method_params();
  std::vector<Scan> scans = testing::two_planar_scans();
  scans[1].pose_covariance = PoseCovariance::from_planar({0.02 * 0.02, 0.0001, 0, 0.0001, 0.03 * 0.03, 0, 0, 0, 0.05 * 0.05});
  auto method = warp ? make_wgpom_method(params, mp, cpu_backend(), *warp) : make_method(name, params, mp, cpu_backend());
  for (const Scan& scan : scans) method->insert(scan);
  method->finish();

  std::vector<ScanObservations> obs(2);
  PreprocessCounts counts;
  for (int s = 0; s < 2; ++s) preprocess_scan(scans[s], params.preprocess, obs[s], counts);
  const std::vector<PoseSigmaPoint> points = pose_sigma_points(*scans[1].pose_covariance);
  ASSERT_EQ(points.size(), 6u);
  GpHyperParams hp;
  hp.covariance = GpCovariance::kMatern32;
  hp.ell_m = 0.3;
  hp.signal_var = 1.0;
  hp.noise_std = 0.1;
  const GaussHermite rule(20);
  int compared = 0, unknown = 0;
  for (int cy = 0; cy < 32; ++cy)
    for (int cx = 0; cx < 32; ++cx) {
      const Vec3d q{(cx + 0.5) * 0.1, (cy + 0.5) * 0.1, 0.0};
      double sum_m = 0, sum_m2 = 0, sum_v = 0, farthest = 0;  // the largest of the hypotheses' nearest
      for (const PoseSigmaPoint& point : points) {
        ScanObservations moved;
        displace_observations(obs[1], point, true, moved);
        std::vector<Vec3d> x;
        std::vector<double> y;
        for (const ScanObservations* o : {&obs[0], &moved}) {
          const Vec3d origin{o->origin.x, o->origin.y, o->origin.z};
          for (const Vec3f& h : o->hits) x.push_back({h.x, h.y, h.z}), y.push_back(1);
          for (const Vec3f& e : o->free_ends) {
            const Vec3d d{e.x - origin.x, e.y - origin.y, e.z - origin.z};
            const double t =
                std::clamp(((q.x - origin.x) * d.x + (q.y - origin.y) * d.y) / (d.x * d.x + d.y * d.y), 0.0, 1.0);
            x.push_back({origin.x + t * d.x, origin.y + t * d.y, origin.z + t * d.z});
            y.push_back(-1);
          }
        }
        double nearest = INFINITY;
        for (const Vec3d& p : x) nearest = std::min(nearest, std::hypot(p.x - q.x, p.y - q.y));
        farthest = std::max(farthest, nearest);
        if (warp)
          for (double& label : y) label = warp->value(label);
        GpPrediction p = dense_gp(x, y, q, hp);
        if (warp) p = unwarp_prediction(p.mean, p.variance, *warp, rule);
        sum_m += p.mean / 6;
        sum_m2 += p.mean * p.mean / 6;
        sum_v += p.variance / 6;
      }
      const std::optional<CellEstimate> e = method->estimate(q.x, q.y, 0.0);
      if (farthest > 0.3 + 1e-9) {
        EXPECT_FALSE(e.has_value()) << cx << "," << cy;
        ++unknown;
        continue;
      }
      if (farthest > 0.3 - 1e-9) continue;  // on the reach boundary: float rounding decides
      ASSERT_TRUE(e.has_value()) << cx << "," << cy;
      EXPECT_NEAR(*e->gp_mean, sum_m, 1e-9) << cx << "," << cy;
      EXPECT_NEAR(*e->variance, sum_v + sum_m2 - sum_m * sum_m, 1e-9) << cx << "," << cy;
      ++compared;
    }
  EXPECT_GT(compared, 100);
  EXPECT_GT(unknown, 100);
  EXPECT_NE(method->backend().device.find("expected sub-map over 6 pose sigma points"), std::string::npos);
}

TEST(GpomPoseUncertainty, ExpectedSubmapEqualsTheDenseMixtureIn2D) { expect_dense_expected_submap("gpom", nullptr); }

TEST(WgpomPoseUncertainty, ExpectedSubmapEqualsTheDenseWarpedMixtureIn2D) {
  const TanhWarp warp = two_term_warp();
  expect_dense_expected_submap("wgpom", &warp);
}

// A zero covariance is no uncertainty: the plain map, every cell bit for bit (PLSC included), by
// the expected sub-map and by the expected kernel.
TEST(GpomPoseUncertainty, ZeroCovarianceGivesThePlainMapExactly) {
  for (const auto& [fusion, name] : {std::pair<PoseFusion, std::string>{PoseFusion::kExpectedSubmap, "gpom"},
                                     {PoseFusion::kExpectedSubmap, "wgpom"},
                                     {PoseFusion::kExpectedKernel, "gpom"},
                                     {PoseFusion::kExpectedKernel, "wgpom"}}) {
    BuildParams params = testing::small_planar_params();
    params.preprocess.pose_fusion = fusion;
    MethodParams mp;
    std::vector<Scan> scans = testing::two_planar_scans();
    auto plain = make_method(name, params, mp, cpu_backend());
    for (const Scan& scan : scans) plain->insert(scan);
    plain->finish();
    for (Scan& scan : scans) scan.pose_covariance = PoseCovariance{};
    auto zero = make_method(name, params, mp, cpu_backend());
    for (const Scan& scan : scans) zero->insert(scan);
    zero->finish();
    int known = 0;
    for (int cy = 0; cy < 32; ++cy)
      for (int cx = 0; cx < 32; ++cx) {
        const double x = (cx + 0.5) * 0.1, y = (cy + 0.5) * 0.1;
        const std::optional<CellEstimate> a = plain->estimate(x, y, 0.0), b = zero->estimate(x, y, 0.0);
        ASSERT_EQ(a.has_value(), b.has_value()) << name << " " << cx << "," << cy;
        if (!a) continue;
        ++known;
        EXPECT_EQ(*a->gp_mean, *b->gp_mean);
        EXPECT_EQ(*a->variance, *b->variance);
        EXPECT_EQ(a->occupancy, b->occupancy);
      }
    EXPECT_GT(known, 100) << name;
    EXPECT_EQ(zero->backend().device, plain->backend().device) << name;
  }
}

// The expected sub-map refuses an uncertain scan whose covariance has another rank (its sigma
// points cannot be paired with the earlier ones); the expected kernel (test_expected_kernel.cpp)
// takes it.
TEST(GpomPoseUncertainty, ExpectedSubmapRefusesAMismatchedRank) {
  BuildParams params = testing::small_planar_params();
  std::vector<Scan> scans = testing::two_planar_scans();
  scans[0].pose_covariance = PoseCovariance::from_planar({0.01, 0, 0, 0, 0.01, 0, 0, 0, 0.001});
  scans[1].pose_covariance = PoseCovariance::from_planar({0.01, 0, 0, 0, 0.01, 0, 0, 0, 0});
  for (const bool named : {false, true}) {
    // Named where the covariances came from (a file's line, ScanSource), when they say.
    if (named) {
      scans[0].pose_covariance_source = "cov.txt line 1";
      scans[1].pose_covariance_source = "cov.txt line 2";
    }
    auto method = make_method("gpom", params, MethodParams{}, cpu_backend());
    method->insert(scans[0]);
    try {
      method->insert(scans[1]);
      ADD_FAILURE() << "a rank-2 covariance after a rank-3 one was accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(named ? "scan 2's pose covariance (cov.txt line 2) has rank 2, the earlier "
                                                   "uncertain scans' 3 (the first: cov.txt line 1; the expected sub-map"
                                                 : "scan 2's pose covariance has rank 2, the earlier uncertain scans' 3 "
                                                   "(the expected sub-map"),
                std::string::npos)
          << e.what();
    }
  }
}

// k below the data: the local model holds the k nearest hits (found by the k-d tree) and the
// nearest points of the k nearest beams (here every beam is one sample: all are candidates).
TEST(GpomMethod, LocalModelHoldsTheKNearestHitsIn3D) {
  BuildParams params;
  params.grid.resolution_m = 0.1;
  params.preprocess.max_range_m = 0;
  params.preprocess.end_margin_m = 0;
  MethodParams mp;
  mp.set("gp-neighbours", 3);
  mp.set("gp-length", 1.2);  // beam samples 0.6 m apart: one per beam, ten in all, fewer than 4k
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-0.3f, 0.3f);
  Scan scan;
  scan.pose.position = {0.05f, 0.05f, 0.05f};
  for (int i = 0; i < 10; ++i) scan.points.push_back({0.05f + u(rng), 0.05f + u(rng), 0.05f + u(rng)});
  auto method = make_method("gpom", params, mp, cpu_backend());
  method->insert(scan);
  GpHyperParams hp;
  hp.covariance = GpCovariance::kMatern32;
  hp.ell_m = 1.2;
  hp.signal_var = 1.0;
  hp.noise_std = 0.1;
  const Vec3d o{0.05f, 0.05f, 0.05f};
  int checked = 0;
  for (int i = -3; i <= 3; ++i)
    for (int j = -3; j <= 3; ++j) {
      const Vec3d q{(i + 0.5) * 0.1, (j + 0.5) * 0.1, 0.05};
      const auto d2 = [&](const Vec3d& p) { return (p.x - q.x) * (p.x - q.x) + (p.y - q.y) * (p.y - q.y) + (p.z - q.z) * (p.z - q.z); };
      std::vector<std::pair<double, Vec3d>> hits, beams;
      for (const Vec3f& h : scan.points) {
        hits.push_back({d2({h.x, h.y, h.z}), {h.x, h.y, h.z}});
        const Vec3d d{h.x - o.x, h.y - o.y, h.z - o.z};
        const double t = std::clamp(((q.x - o.x) * d.x + (q.y - o.y) * d.y + (q.z - o.z) * d.z) /
                                        (d.x * d.x + d.y * d.y + d.z * d.z), 0.0, 1.0);
        const Vec3d p{o.x + t * d.x, o.y + t * d.y, o.z + t * d.z};
        beams.push_back({d2(p), p});
      }
      std::sort(hits.begin(), hits.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
      std::sort(beams.begin(), beams.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
      std::vector<Vec3d> x;
      std::vector<double> y;
      for (int k = 0; k < 3; ++k) x.push_back(hits[k].second), y.push_back(1);
      for (int k = 0; k < 3; ++k) x.push_back(beams[k].second), y.push_back(-1);
      const GpPrediction ref = dense_gp(x, y, q, hp);
      const std::optional<CellEstimate> e = method->estimate(q.x, q.y, q.z);
      ASSERT_TRUE(e.has_value());
      EXPECT_NEAR(*e->gp_mean, ref.mean, 1e-9) << i << "," << j;
      EXPECT_NEAR(*e->variance, ref.variance, 1e-9) << i << "," << j;
      ++checked;
    }
  EXPECT_EQ(checked, 49);
}

TEST(GpomMethod, RefusesMixingPlanarAnd3DScans) {
  BuildParams params;
  params.grid.resolution_m = 0.1;
  Scan planar;
  planar.pose.position = {0, 0, 0.5f};
  planar.points = {{1, 0, 0.5f}, {0, 1, 0.5f}};
  Scan solid = planar;
  solid.points.push_back({1, 1, 0.7f});
  auto a = make_method("gpom", params, MethodParams{}, cpu_backend());
  a->insert(planar);
  EXPECT_THROW(a->insert(solid), std::invalid_argument);
  Scan higher = planar;
  higher.pose.position.z = 0.6f;
  for (Vec3f& p : higher.points) p.z = 0.6f;
  EXPECT_THROW(a->insert(higher), std::invalid_argument);
  auto b = make_method("gpom", params, MethodParams{}, cpu_backend());
  b->insert(solid);
  EXPECT_THROW(b->insert(planar), std::invalid_argument);
}

// A planar scene of 4 simulated scans in folder d (d/sim/scans), and `method`'s held-out
// evaluation on it through the command line (its JSON; empty after a failure).
nlohmann::json simulate_and_hold_out(const std::string& d, const std::string& method, const std::string& flags) {
  const std::string cli = std::string(BGKMAP_CLI) + " ";
  const auto sim = testing::run_command(cli + "simulate structured --sensor planar --scans 4 -q --truth-resolution 0 -o " + d + "sim");
  EXPECT_EQ(sim.status, 0) << sim.output;
  const auto r = testing::run_command(cli + "eval --holdout 0.2 --seed 1 " + d + "sim/scans --method " + method +
                                      " --max-range 8 --threads 2 " + flags + " --json " + d + "e.json");
  EXPECT_EQ(r.status, 0) << r.output;
  if (sim.status != 0 || r.status != 0) return {};
  std::ifstream in(d + "e.json");
  return nlohmann::json::parse(in);
}

// Build and held-out evaluation through the command line on a simulated planar scene.
TEST(GpomCli, HoldoutOnASimulatedPlanarScene) {
  const auto dir = testing::make_temp_dir("gpom-cli");
  const std::string cli = std::string(BGKMAP_CLI) + " ", d = dir.string() + "/";
  const nlohmann::json e = simulate_and_hold_out(d, "gpom", "--resolution 0.1 --gp-length 0.5");
  ASSERT_FALSE(e.is_null());
  EXPECT_EQ(e["method"], "gpom");
  EXPECT_GT(e["auc"].get<double>(), 0.95);
  EXPECT_LT(e["nll"].get<double>(), 0.4);
  const auto b = testing::run_command(cli + "build -q " + d + "sim/scans --method gpom --max-range 8 --gp-covariance sparse "
                                      "--gp-neighbours 10 -o " + d + "m.ot --report " + d + "r.json");
  ASSERT_EQ(b.status, 0) << b.output;
  std::ifstream rin(d + "r.json");
  const nlohmann::json params = nlohmann::json::parse(rin)["params"];
  EXPECT_EQ(params["gp_covariance"], "sparse");
  EXPECT_DOUBLE_EQ(params["gp_neighbours"].get<double>(), 10);
  EXPECT_TRUE(std::filesystem::exists(d + "m.ot"));
  const auto bad = testing::run_command(cli + "build -q " + d + "sim/scans --method gpom --gp-covariance rbf -o " + d + "x.ot");
  EXPECT_NE(bad.status, 0);
  // The neural-network covariance: built on the CPU, local models centred at their queries; with the
  // expected kernel (a covariance of the distance) refused in one line.
  const auto nn = testing::run_command(cli + "build -q " + d + "sim/scans --method gpom --max-range 8 --gp-covariance nn "
                                       "--gp-neighbours 10 -o " + d + "nn.ot --report " + d + "nn.json");
  ASSERT_EQ(nn.status, 0) << nn.output;
  std::ifstream nn_in(d + "nn.json");
  const std::string nn_report = nlohmann::json::parse(nn_in).dump();
  EXPECT_NE(nn_report.find("neural-network covariance, each local model centred at its query"), std::string::npos)
      << nn_report.substr(0, 600);
  const auto nn_kernel = testing::run_command(cli + "build -q " + d + "sim/scans --method gpom --gp-covariance nn "
                                              "--pose-fusion kernel -o " + d + "x.ot");
  EXPECT_NE(nn_kernel.status, 0);
  EXPECT_NE(nn_kernel.output.find("takes a covariance of the distance"), std::string::npos) << nn_kernel.output;
  EXPECT_NE(testing::run_command(cli + "build -q " + d + "sim/scans --method gpom --gp-covariance nn --gp-range-sigma 0.01 -o " +
                                 d + "x.ot").status, 0);
  EXPECT_EQ(std::count(nn_kernel.output.begin(), nn_kernel.output.end(), '\n'), 1) << nn_kernel.output;
  // The same parameters from a config file, a bad name refused naming the file.
  {
    std::ofstream cfg(d + "g.yaml");
    cfg << "method: gpom\ngp_covariance: sparse\ngp-length: 0.4\nmax_range: 8\n";
    std::ofstream bad_cfg(d + "bad.yaml");
    bad_cfg << "method: gpom\ngp_covariance: rbf\n";
  }
  const auto c = testing::run_command(cli + "build -q " + d + "sim/scans --config " + d + "g.yaml -o " + d + "c.ot --report " +
                                      d + "c.json");
  ASSERT_EQ(c.status, 0) << c.output;
  std::ifstream config_in(d + "c.json");
  const nlohmann::json config_params = nlohmann::json::parse(config_in)["params"];
  EXPECT_EQ(config_params["method"], "gpom");
  EXPECT_EQ(config_params["gp_covariance"], "sparse");
  EXPECT_DOUBLE_EQ(config_params["gp_length"].get<double>(), 0.4);
  const auto refused = testing::run_command(cli + "build -q " + d + "sim/scans --config " + d + "bad.yaml -o " + d + "y.ot");
  EXPECT_NE(refused.status, 0);
  EXPECT_NE(refused.output.find("bad.yaml"), std::string::npos) << refused.output;
  EXPECT_NE(refused.output.find("rbf"), std::string::npos) << refused.output;
  // Station keeping: one scan inserted again and again; gpom reports its local GP's latent variance.
  const auto s = testing::run_command(cli + "station-keeping -q " + d + "sim/scans/scan_00000.pcd --cell near:1.5,3.3,1 "
                                      "--repeats 1,3 --methods gpom --max-range 8 --threads 2 --json " + d + "s.json");
  ASSERT_EQ(s.status, 0) << s.output;
  std::ifstream sin(d + "s.json");
  const nlohmann::json keeping = nlohmann::json::parse(sin);
  const std::string dump = keeping.dump();
  EXPECT_NE(dump.find("gp_local_latent"), std::string::npos) << dump.substr(0, 400);
  EXPECT_NE(dump.find("\"known\":true"), std::string::npos) << dump.substr(0, 400);
  std::filesystem::remove_all(dir);
}

// A kernel matrix that is not positive definite (a noise too small for inputs this close) was
// thrown inside the OpenMP loops that solve the local models, and aborted the process (status
// 134, std::terminate); the GP methods end in one line naming --gp-noise, status 1, no map written.
TEST(GpomCli, AKernelMatrixThatIsNotPositiveDefiniteEndsInOneLineNamingGpNoise) {
  const auto dir = testing::make_temp_dir("gpom-not-pd");
  const std::string cli = std::string(BGKMAP_CLI) + " ", d = dir.string() + "/";
  const auto sim = testing::run_command(cli + "simulate structured --sensor planar --scans 3 --drift 0.01,0.002 -q "
                                        "--truth-resolution 0 -o " + d + "sim");
  ASSERT_EQ(sim.status, 0) << sim.output;
  // The poses file with each scan's pose covariance made huge (as huge as is taken: standard
  // deviations of 1e6 m and 3 rad, pose_covariance_problem): the expected kernel's matrix is then
  // nearly constant.
  {
    std::ifstream in(d + "sim/poses.txt");
    std::ofstream out(d + "huge.txt");
    std::string line;
    while (std::getline(in, line)) {
      if (line.empty() || line[0] == '#') continue;
      std::istringstream fields(line);
      std::string pose;
      for (int k = 0; k < 8; ++k) {
        std::string f;
        fields >> f;
        pose += f + " ";
      }
      out << pose << "1e12 0 0 0 1e12 0 0 0 9\n";
    }
  }
  const std::string common = "build -q " + d + "sim/scans --max-range 14 --2d --plane-z 1 --threads 2 ";
  for (const std::string& flags : std::vector<std::string>{
           "--method gpom --gp-covariance se --gp-noise 1e-12", "--method gpom --gp-noise 1e-8 --gp-length 2",
           "--method gpom --gp-covariance sparse --gp-noise 1e-12", "--method wgpom --gp-noise 1e-9 --gp-length 3",
           "--method gpoctomap --gp-noise 1e-12 --ell 1",
           "--method gpom --pose-fusion kernel --pose-covariance " + d + "huge.txt"}) {
    testing::expect_gp_not_positive_definite(testing::run_command(cli + common + flags + " -o " + d + "m.bt"), flags,
                                             d + "m.bt");
  }
  std::filesystem::remove_all(dir);
}

// ---- wgpom ----

TEST(GaussHermite, IntegratesPolynomialsExactly) {
  // integral x^k exp(-x^2) dx = Gamma((k + 1) / 2) for even k, 0 for odd k.
  for (const int n : {1, 2, 5, 20, 40}) {
    const GaussHermite rule(n);
    ASSERT_EQ(rule.size(), n);
    for (int k = 0; k < 2 * n; ++k) {
      double sum = 0, magnitude = 0;  // the terms' magnitude bounds the rounding of odd moments
      for (int i = 0; i < n; ++i) {
        const double term = rule.weights()[i] * std::pow(rule.nodes()[i], k);
        sum += term;
        magnitude += std::abs(term);
      }
      const double exact = k % 2 ? 0.0 : std::tgamma((k + 1) / 2.0);
      EXPECT_NEAR(sum, exact, 1e-13 * magnitude) << n << " " << k;
    }
    EXPECT_TRUE(std::is_sorted(rule.nodes().begin(), rule.nodes().end()));
  }
  const GaussHermite rule(10);
  EXPECT_NEAR(rule.expectation(0.7, 0.3, [](double z) { return z * z; }), 0.7 * 0.7 + 0.3, 1e-13);
  EXPECT_THROW(GaussHermite(0), std::invalid_argument);
}

TanhWarp test_warp() {
  TanhWarp warp;
  warp.d = 0.6;
  warp.a = {1.2, 0.3, 2.0};
  warp.b = {3.0, 0.5, 1.5};
  warp.c = {-0.8, 0.2, 1.1};
  return warp;
}

TEST(WarpedGp, WarpDerivativeAndInverse) {
  const TanhWarp warp = test_warp();
  for (double y = -4; y <= 4; y += 0.173) {
    const double h = 1e-6;
    EXPECT_NEAR(warp.derivative(y), (warp.value(y + h) - warp.value(y - h)) / (2 * h), 1e-7) << y;
    EXPECT_NEAR(warp.inverse(warp.value(y)), y, 1e-12) << y;
    EXPECT_GT(warp.value(y + 0.01), warp.value(y));
  }
  EXPECT_NEAR(warp.inverse(1e4), (1e4 - 3.5) / 0.6, 1e-9 * 1e4 / 0.6);  // far out: the linear term's inverse
  const TanhWarp back = TanhWarp::from_parameters(warp.parameters());
  EXPECT_NEAR(back.value(0.37), warp.value(0.37), 1e-14);
  EXPECT_EQ(TanhWarp{}.inverse(0.25), 0.25);
}

std::vector<LocalModel> random_local_models(uint32_t seed, int count, int size) {
  std::mt19937 rng(seed);
  std::vector<LocalModel> models(count);
  for (LocalModel& m : models) {
    m.train = random_points(rng, size, 1.5);
    for (const Vec3d& p : m.train) m.labels.push_back(p.x + 0.5 * p.y > 1.0 ? 1.0 : -1.0);
  }
  return models;
}

// log N(z; 0, K~) + sum log g'(y) by Gauss-Jordan elimination (log-determinant from the pivots).
double dense_warped_log_likelihood(const LocalModel& m, const TanhWarp& warp, const GpHyperParams& hp) {
  const size_t n = m.train.size();
  std::vector<std::vector<double>> a(n, std::vector<double>(n + 1));
  std::vector<double> z(n);
  for (size_t i = 0; i < n; ++i) z[i] = warp.value(m.labels[i]);
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = 0; j < n; ++j) {
      a[i][j] = reference_covariance(m.train[i], m.train[j], hp) + (i == j ? hp.noise_std * hp.noise_std : 0);
    }
    a[i][n] = z[i];
  }
  double log_det = 0;
  for (size_t c = 0; c < n; ++c) {  // no pivoting needed: K~ is positive definite
    log_det += std::log(a[c][c]);
    for (size_t r = c + 1; r < n; ++r) {
      const double f = a[r][c] / a[c][c];
      for (size_t k = c; k <= n; ++k) a[r][k] -= f * a[c][k];
    }
  }
  std::vector<double> x(n);  // back substitution: K~ x = z
  for (size_t r = n; r-- > 0;) {
    double v = a[r][n];
    for (size_t k = r + 1; k < n; ++k) v -= a[r][k] * x[k];
    x[r] = v / a[r][r];
  }
  double quad = 0, jacobian = 0;
  for (size_t i = 0; i < n; ++i) quad += z[i] * x[i], jacobian += std::log(warp.derivative(m.labels[i]));
  return -0.5 * quad - 0.5 * log_det - 0.5 * n * std::log(2 * M_PI) + jacobian;
}

GpHyperParams matern(double ell, double signal, double noise) {
  GpHyperParams hp;
  hp.covariance = GpCovariance::kMatern32;
  hp.ell_m = ell;
  hp.signal_var = signal;
  hp.noise_std = noise;
  return hp;
}

TEST(WarpedGp, LogLikelihoodEqualsTheDenseReferenceAndItsGradientFiniteDifferences) {
  const GpHyperParams hp = matern(0.6, 1.0, 0.1);
  const std::vector<LocalModel> models = random_local_models(11, 3, 30);
  const WarpTrainingSet set(models, hp);
  for (const TanhWarp& warp : {TanhWarp{}, test_warp()}) {
    double expected = 0;
    for (const LocalModel& m : models) expected += dense_warped_log_likelihood(m, warp, hp);
    std::vector<double> gradient;
    const double got = set.log_likelihood(warp, &gradient);
    EXPECT_NEAR(got, expected, 1e-9 * std::abs(expected));
    const std::vector<double> theta = warp.parameters();
    ASSERT_EQ(gradient.size(), theta.size());
    for (size_t k = 0; k < theta.size(); ++k) {
      const double h = 1e-6;
      std::vector<double> up = theta, down = theta;
      up[k] += h;
      down[k] -= h;
      const double fd = (set.log_likelihood(TanhWarp::from_parameters(up)) -
                         set.log_likelihood(TanhWarp::from_parameters(down))) / (2 * h);
      EXPECT_NEAR(gradient[k], fd, 1e-5 * std::max(1.0, std::abs(fd))) << k;
    }
  }
}

TEST(WarpedGp, LearnedWarpIsTheBestOfTheBoxItSearches) {
  const GpHyperParams hp = matern(0.6, 1.0, 0.1);
  const WarpTrainingSet set(random_local_models(12, 8, 25), hp);
  WarpLearning options;
  options.terms = 2;
  const TanhWarp learned = learn_warp(set, options);
  ASSERT_EQ(learned.terms(), 2u);
  const double best = set.log_likelihood(learned);
  EXPECT_GT(best, set.log_likelihood(TanhWarp{}));
  // No better warp among random ones in the box, nor one step off it along any parameter that
  // is inside its range (at a bound the gradient may point out of the box).
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> u(0, 1);
  for (int trial = 0; trial < 200; ++trial) {
    TanhWarp w;
    w.d = std::exp(std::log(0.2) + u(rng) * std::log(100.0));
    for (int j = 0; j < 2; ++j) {
      w.a.push_back(std::exp(std::log(1e-3) + u(rng) * std::log(2000.0)));
      w.b.push_back(std::exp(std::log(1e-2) + u(rng) * std::log(100.0)));
      w.c.push_back(-2 + 4 * u(rng));
    }
    EXPECT_LE(set.log_likelihood(w), best);
  }
  std::vector<double> gradient;
  set.log_likelihood(learned, &gradient);
  const std::vector<double> theta = learned.parameters();
  const double lo[4] = {std::log(0.2), std::log(1e-3), std::log(1e-2), -2}, hi[4] = {std::log(20.0), std::log(2.0), 0.0, 2};
  for (size_t k = 0; k < theta.size(); ++k) {
    const int kind = k == 0 ? 0 : 1 + static_cast<int>((k - 1) % 3);
    if (theta[k] > lo[kind] + 1e-3 && theta[k] < hi[kind] - 1e-3) {
      EXPECT_LT(std::abs(gradient[k]), 1e-3 * std::max(1.0, std::abs(best))) << k;
    }
  }
  // Deterministic, and no terms or no data: the identity.
  EXPECT_EQ(learn_warp(set, options).parameters(), learned.parameters());
  options.terms = 0;
  EXPECT_EQ(learn_warp(set, options).terms(), 0u);
}

TEST(GpHyperparameters, LogLikelihoodEqualsTheDenseReferenceAndItsGradientFiniteDifferences) {
  const std::vector<LocalModel> models = random_local_models(14, 3, 30);
  for (const GpCovariance covariance : {GpCovariance::kMatern32, GpCovariance::kSparse, GpCovariance::kSquaredExponential,
                                        GpCovariance::kNeuralNetwork}) {
    GpHyperParams hp = matern(0.7, 1.3, 0.2);
    hp.covariance = covariance;
    double expected = 0;  // the warped likelihood with the identity warp is the plain one
    for (const LocalModel& m : models) expected += dense_warped_log_likelihood(m, TanhWarp{}, hp);
    std::vector<double> gradient;
    EXPECT_NEAR(gp_log_marginal_likelihood(models, hp, &gradient), expected, 1e-9 * std::abs(expected));
    const std::vector<double> theta = hyperparameters_vector(hp);
    ASSERT_EQ(gradient.size(), 3u);
    for (size_t k = 0; k < 3; ++k) {
      const double h = 1e-6;
      std::vector<double> up = theta, down = theta;
      up[k] += h;
      down[k] -= h;
      const double fd = (gp_log_marginal_likelihood(models, hyperparameters_from(up, hp)) -
                         gp_log_marginal_likelihood(models, hyperparameters_from(down, hp))) / (2 * h);
      EXPECT_NEAR(gradient[k], fd, 1e-5 * std::max(1.0, std::abs(fd))) << k;
    }
  }
}

TEST(GpHyperparameters, LearnedValuesAreTheBestOfTheBox) {
  const std::vector<LocalModel> models = random_local_models(15, 6, 30);
  const GpHyperParams start = matern(0.2, 1.0, 0.5);
  const HyperparameterLearning options;
  const GpHyperParams learned = learn_hyperparameters(models, start, options);
  EXPECT_EQ(learned.covariance, GpCovariance::kMatern32);
  std::vector<double> gradient;
  const double best = gp_log_marginal_likelihood(models, learned, &gradient);
  EXPECT_GT(best, gp_log_marginal_likelihood(models, start));
  std::mt19937 rng(16);
  std::uniform_real_distribution<double> u(0, 1);
  for (int trial = 0; trial < 100; ++trial) {
    const GpHyperParams other = hyperparameters_from(
        {std::log(0.05) + u(rng) * std::log(100.0), std::log(0.01) + u(rng) * std::log(1e4), std::log(0.01) + u(rng) * std::log(100.0)}, start);
    EXPECT_LE(gp_log_marginal_likelihood(models, other), best);
  }
  // Inside the box the maximum is a stationary point.
  const std::vector<double> theta = hyperparameters_vector(learned);
  const double lo[3] = {std::log(0.05), std::log(0.01), std::log(0.01)}, hi[3] = {std::log(5.0), std::log(100.0), 0.0};
  for (size_t k = 0; k < 3; ++k)
    if (theta[k] > lo[k] + 1e-3 && theta[k] < hi[k] - 1e-3) {
      EXPECT_LT(std::abs(gradient[k]), 1e-3 * std::max(1.0, std::abs(best))) << k;
    }
  EXPECT_EQ(learn_hyperparameters({}, start, options).ell_m, 0.2);
}

// E[g^-1(z)] and its variance by a fine trapezoid over z (mean +- 12 sd), g^-1 by bisection.
GpPrediction integrated_unwarp(double mean, double variance, const TanhWarp& warp) {
  const auto inverse = [&](double z) {
    double lo = -1e3, hi = 1e3;
    for (int i = 0; i < 64; ++i) (warp.value(0.5 * (lo + hi)) > z ? hi : lo) = 0.5 * (lo + hi);
    return 0.5 * (lo + hi);
  };
  const int steps = 8000;
  const double sd = std::sqrt(variance), from = mean - 12 * sd, h = 24 * sd / steps;
  double m0 = 0, m1 = 0, m2 = 0;
  for (int i = 0; i <= steps; ++i) {
    const double z = from + i * h, w = (i == 0 || i == steps ? 0.5 : 1.0) * std::exp(-0.5 * (z - mean) * (z - mean) / variance);
    const double y = inverse(z);
    m0 += w, m1 += w * y, m2 += w * y * y;
  }
  GpPrediction p;
  p.mean = m1 / m0;
  p.variance = m2 / m0 - p.mean * p.mean;
  return p;
}

TEST(WarpedGp, UnwarpedPredictionEqualsTheIntegral) {
  const GaussHermite rule(20);  // wgpom's
  // The identity: the latent mean and variance themselves.
  const GpPrediction same = unwarp_prediction(0.3, 0.2, TanhWarp{}, rule);
  EXPECT_NEAR(same.mean, 0.3, 1e-14);
  EXPECT_NEAR(same.variance, 0.2, 1e-14);
  // A smoother warp (b up to 3, outside the box), and the steepest of learn_warp's box (three terms stacked at full height and
  // slope, the linear term at its least): the inverse bends most there. Latent means at the
  // warped labels and between them, latent variances up to the prior's.
  TanhWarp steep;
  steep.d = 0.2;
  steep.a = {2, 2, 2};
  steep.b = {1, 1, 1};
  steep.c = {-1, -1, -1};
  for (const auto& [warp, tolerance] : {std::pair{test_warp(), 1e-3}, std::pair{steep, 1e-2}})
    for (const double y : {-1.0, 0.4, 1.0})
      for (const double variance : {0.01, 0.1, 1.0}) {
        const double mean = warp.value(y);
        const GpPrediction got = unwarp_prediction(mean, variance, warp, rule);
        const GpPrediction ref = integrated_unwarp(mean, variance, warp);
        EXPECT_NEAR(got.mean, ref.mean, tolerance) << y << " " << variance;
        EXPECT_NEAR(got.variance, ref.variance, tolerance) << y << " " << variance;
      }
}

// No warp terms: wgpom's map is gpom's, cell for cell.
TEST(WgpomMethod, NoTermsGivesGpomsMap) {
  const auto dir = testing::make_temp_dir("wgpom-identity");
  ASSERT_EQ(testing::run_command(std::string(BGKMAP_CLI) + " simulate structured --sensor planar --scans 2 -q --truth-resolution 0 -o " +
                                 dir.string() + "/sim").status, 0);
  BuildParams params;
  params.grid.resolution_m = 0.2;
  params.preprocess.max_range_m = 8;
  MethodParams mp;
  mp.set("wgp-terms", 0);
  auto gpom = make_method("gpom", params, mp, cpu_backend());
  auto wgpom = make_method("wgpom", params, mp, cpu_backend());
  ScanSource source({dir.string() + "/sim/scans"});
  Scan scan;
  double z = 0;
  while (source.next(scan)) gpom->insert(scan), wgpom->insert(scan), z = scan.pose.position.z;
  gpom->finish();
  wgpom->finish();
  ASSERT_EQ(gpom->known_cells(), wgpom->known_cells());
  ASSERT_GT(gpom->known_cells(), 1000u);
  int compared = 0;
  for (double x = -2; x < 12; x += 0.2)
    for (double y = -2; y < 12; y += 0.2) {
      const auto a = gpom->estimate(x, y, z), b = wgpom->estimate(x, y, z);
      ASSERT_EQ(a.has_value(), b.has_value());
      if (!a) continue;
      EXPECT_NEAR(*b->gp_mean, *a->gp_mean, 1e-12);
      EXPECT_NEAR(*b->variance, *a->variance, 1e-12);
      EXPECT_NEAR(b->occupancy, a->occupancy, 1e-9);
      ++compared;
    }
  EXPECT_GT(compared, 500);
  std::filesystem::remove_all(dir);
}

// Held-out evaluation, build and station keeping through the command line; a bad flag refused.
TEST(WgpomCli, HoldoutBuildAndStationKeeping) {
  const auto dir = testing::make_temp_dir("wgpom-cli");
  const std::string cli = std::string(BGKMAP_CLI) + " ", d = dir.string() + "/";
  const nlohmann::json e = simulate_and_hold_out(d, "wgpom", "--resolution 0.2");
  ASSERT_FALSE(e.is_null());
  EXPECT_EQ(e["method"], "wgpom");
  EXPECT_GT(e["auc"].get<double>(), 0.93);  // gpom on the same split: 0.944
  EXPECT_LT(e["nll"].get<double>(), 0.45);
  const auto b = testing::run_command(cli + "build -q " + d + "sim/scans --method wgpom --max-range 8 --wgp-terms 2 "
                                      "--gp-hyperparameters learn -o " + d + "m.bt --report " + d + "r.json");
  ASSERT_EQ(b.status, 0) << b.output;
  std::ifstream rin(d + "r.json");
  const nlohmann::json params = nlohmann::json::parse(rin)["params"];
  EXPECT_DOUBLE_EQ(params["wgp_terms"].get<double>(), 2);
  EXPECT_EQ(params["gp_hyperparameters"], "learn");
  std::ifstream rin2(d + "r.json");  // the learned covariance and warp, in the backend's description
  const std::string report = nlohmann::json::parse(rin2).dump();
  EXPECT_NE(report.find("warp g(y) = "), std::string::npos) << report.substr(0, 600);
  EXPECT_NE(report.find("learned covariance: length "), std::string::npos) << report.substr(0, 600);
  EXPECT_TRUE(std::filesystem::exists(d + "m.bt"));
  const auto bad = testing::run_command(cli + "build -q " + d + "sim/scans --method wgpom --wgp-terms 1.5 -o " + d + "x.ot");
  EXPECT_NE(bad.status, 0);
  EXPECT_NE(bad.output.find("wgp-terms"), std::string::npos) << bad.output;
  const auto native = testing::run_command(cli + "build -q " + d + "sim/scans --method wgpom -o " + d + "x.bgk");
  EXPECT_NE(native.status, 0);
  const auto s = testing::run_command(cli + "station-keeping -q " + d + "sim/scans/scan_00000.pcd --cell near:1.5,3.3,1 "
                                      "--repeats 1,3 --methods wgpom --max-range 8 --threads 2 --json " + d + "s.json");
  ASSERT_EQ(s.status, 0) << s.output;
  std::ifstream sin(d + "s.json");
  const std::string dump = nlohmann::json::parse(sin).dump();
  EXPECT_NE(dump.find("wgp_local_label"), std::string::npos) << dump.substr(0, 400);
  EXPECT_NE(dump.find("\"known\":true"), std::string::npos) << dump.substr(0, 400);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap
