// gpom's paper mode (--gp-mode paper, IJRR 2012) against plain references: the neural-network
// covariance with a learned S (eq. 7) against its formula, its log marginal likelihood (eq. 9)
// against Gauss-Jordan elimination and its gradient against finite differences, the learner
// recovering the hyper-parameters of data drawn from a GP with known ones, the prior far from
// data through PLSC, and the local models' 15 + 15 neighbours.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/methods/method.hpp"
#include "methods/gp/gp_regression.hpp"
#include "methods/gp/neural_network_learning.hpp"
#include "methods/gpom/gpom_method.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

using testing::cpu_backend;

// IJRR eq. 7 written out, times Williams' 2/pi: s2 (2/pi) asin(2 a~'S b~ / sqrt((1 + 2 a~'S a~)(1 + 2 b~'S b~))).
double eq7(const Vec3d& a, const Vec3d& b, const std::array<double, 4>& s, double s2) {
  const double ta[4] = {1, a.x, a.y, a.z}, tb[4] = {1, b.x, b.y, b.z};
  double ab = 0, aa = 0, bb = 0;
  for (int p = 0; p < 4; ++p) {
    ab += ta[p] * s[p] * tb[p];
    aa += ta[p] * s[p] * ta[p];
    bb += tb[p] * s[p] * tb[p];
  }
  return s2 * 2 / M_PI * std::asin(2 * ab / std::sqrt((1 + 2 * aa) * (1 + 2 * bb)));
}

GpHyperParams paper_hp(const std::array<double, 4>& s, double s2, double sn) {
  GpHyperParams hp;
  hp.covariance = GpCovariance::kNeuralNetwork;
  hp.nn_sigma = s;
  hp.signal_var = s2;
  hp.noise_std = sn;
  return hp;
}

// log N(y; 0, K + sn^2 I) by Gauss-Jordan elimination (the log-determinant from the pivots).
double dense_log_likelihood(const LocalModel& m, const GpHyperParams& hp) {
  const size_t n = m.train.size();
  std::vector<std::vector<double>> a(n, std::vector<double>(n + 1));
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = 0; j < n; ++j)
      a[i][j] = eq7(m.train[i], m.train[j], hp.nn_sigma, hp.signal_var) + (i == j ? hp.noise_std * hp.noise_std : 0);
    a[i][n] = m.labels[i];
  }
  double log_det = 0;
  for (size_t c = 0; c < n; ++c) {  // K is positive definite: no pivoting needed
    log_det += std::log(a[c][c]);
    for (size_t r = 0; r < n; ++r) {
      if (r == c) continue;
      const double f = a[r][c] / a[c][c];
      for (size_t q = c; q <= n; ++q) a[r][q] -= f * a[c][q];
    }
  }
  double fit = 0;
  for (size_t i = 0; i < n; ++i) fit += m.labels[i] * a[i][n] / a[i][i];
  return -0.5 * fit - 0.5 * log_det - 0.5 * double(n) * std::log(2 * M_PI);
}

LocalModel random_model(uint32_t seed, int size, int dims) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-3, 3);
  LocalModel m;
  for (int i = 0; i < size; ++i) {
    const Vec3d p{u(rng), u(rng), dims == 3 ? u(rng) : 0.0};
    m.train.push_back(p);
    m.labels.push_back(p.x + 0.5 * p.y - 0.3 * p.z > 0.4 ? 1.0 : -1.0);
  }
  return m;
}

TEST(GpomPaperCovariance, NeuralNetworkWithSigmaIsEq7) {
  const std::array<double, 4> s{0.7, 2.5, 0.3, 1.9};
  const GpHyperParams hp = paper_hp(s, 1.7, 0.1);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-5, 5);
  for (int i = 0; i < 200; ++i) {
    const Vec3d a{u(rng), u(rng), u(rng)}, b{u(rng), u(rng), u(rng)};
    EXPECT_NEAR(gp_covariance(a, b, hp), eq7(a, b, s, 1.7), 1e-13) << i;
  }
  // Not translation invariant: the world's frame matters, as the paper's covariance.
  const Vec3d a{0.1, 0.2, 0}, b{0.4, -0.3, 0}, shift{5, 5, 0};
  EXPECT_GT(std::abs(gp_covariance(a, b, hp) - gp_covariance({a.x + shift.x, a.y + shift.y, 0},
                                                             {b.x + shift.x, b.y + shift.y, 0}, hp)),
            1e-3);
}

TEST(GpomPaperLearning, LikelihoodEqualsTheDenseReferenceAndItsGradientFiniteDifferences) {
  for (const int dims : {2, 3}) {
    const LocalModel m = random_model(5 + dims, 25, dims);
    const GpHyperParams hp = paper_hp({0.8, 1.3, 0.6, dims == 3 ? 0.9 : 0.0}, 1.4, 0.2);
    std::vector<double> gradient;
    const double value = neural_network_log_likelihood(m, hp, dims, &gradient);
    EXPECT_NEAR(value, dense_log_likelihood(m, hp), 1e-9 * std::abs(value)) << dims;
    const std::vector<double> theta = neural_network_vector(hp, dims);
    ASSERT_EQ(gradient.size(), size_t(dims) + 3);
    for (size_t k = 0; k < theta.size(); ++k) {
      const double h = 1e-6;
      std::vector<double> up = theta, down = theta;
      up[k] += h;
      down[k] -= h;
      const double fd = (neural_network_log_likelihood(m, neural_network_from(up, hp, dims), dims) -
                         neural_network_log_likelihood(m, neural_network_from(down, hp, dims), dims)) /
                        (2 * h);
      EXPECT_NEAR(gradient[k], fd, 1e-5 * std::max(1.0, std::abs(fd))) << dims << " " << k;
    }
  }
}

// Inputs in [-3, 3]^2, labels drawn from a GP with the neural-network covariance of known S, s2
// and sn (by the Cholesky factor of its K~ and a seeded normal draw).
LocalModel draw_from_gp(const GpHyperParams& truth, int size, uint32_t seed) {
  LocalModel m = random_model(seed, size, 2);
  const Eigen::Index n = size;
  Eigen::MatrixXd k(n, n);
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index j = 0; j < n; ++j)
      k(i, j) = eq7(m.train[i], m.train[j], truth.nn_sigma, truth.signal_var) +
                (i == j ? truth.noise_std * truth.noise_std : 0);
  std::mt19937 rng(seed + 1);
  std::normal_distribution<double> normal(0, 1);
  Eigen::VectorXd z(n);
  for (Eigen::Index i = 0; i < n; ++i) z(i) = normal(rng);
  const Eigen::VectorXd y = Eigen::LLT<Eigen::MatrixXd>(k).matrixL() * z;
  for (Eigen::Index i = 0; i < n; ++i) m.labels[i] = y(i);
  return m;
}

TEST(GpomPaperLearning, RecoversTheHyperparametersOfDataDrawnFromTheGp) {
  const GpHyperParams truth = paper_hp({1.0, 0.3, 0.1, 0.0}, 1.0, 0.1);
  LocalModel train = draw_from_gp(truth, 400, 21), test;
  for (size_t i = 300; i < train.train.size(); ++i) {
    test.train.push_back(train.train[i]);
    test.labels.push_back(train.labels[i]);
  }
  train.train.resize(300);
  train.labels.resize(300);
  GpHyperParams start = paper_hp({1.0, 4.0, 4.0, 0.0}, 0.3, 0.3);  // l = 0.5 m, as gpom's default length
  const GpHyperParams learned = learn_neural_network(train, start, NeuralNetworkLearning{});
  // At least as likely as the truth (the optimiser's part).
  EXPECT_GE(neural_network_log_likelihood(train, learned, 2), neural_network_log_likelihood(train, truth, 2) - 1e-6);
  // The noise, and the GP: its posterior at 100 held-out points as the true one's. S and s2 alone are
  // weakly identified (a larger bias S_0 with a smaller s2 gives nearly the same functions).
  EXPECT_NEAR(learned.noise_std, 0.1, 0.02);  // within 20 %
  const std::vector<GpPrediction> got = gp_predict(train.train, train.labels, test.train, learned);
  const std::vector<GpPrediction> want = gp_predict(train.train, train.labels, test.train, truth);
  double mean_error = 0, spread = 0, sd_error = 0;
  for (size_t i = 0; i < test.train.size(); ++i) {
    mean_error += (got[i].mean - want[i].mean) * (got[i].mean - want[i].mean);
    spread += want[i].mean * want[i].mean;
    sd_error = std::max(sd_error, std::abs(std::sqrt(got[i].variance) - std::sqrt(want[i].variance)));
  }
  EXPECT_LT(std::sqrt(mean_error / spread), 0.05);  // relative RMS of the posterior means
  EXPECT_LT(sd_error, 0.03);                          // the posterior standard deviations
  EXPECT_EQ(learned.nn_sigma[3], 0.0);  // 2-D: no weight on z
  // Deterministic: the same seed, the same values.
  const GpHyperParams again = learn_neural_network(train, start, NeuralNetworkLearning{});
  EXPECT_EQ(again.signal_var, learned.signal_var);
  EXPECT_EQ(again.nn_sigma, learned.nn_sigma);
}

// Two planar scans far apart (origins (0.5, 0.5) and (5, 5)), 40 returns each on an arc 0.4-0.6 m
// out: the data's bounding box spans four blocks of 3.2 m, one of them ((1, 0)) far from both.
std::vector<Scan> two_far_scans() {
  std::vector<Scan> scans;
  for (const double o : {0.5, 5.0}) {
    Scan scan;
    scan.pose.position = {float(o), float(o), 0.0f};
    for (int i = 0; i < 40; ++i) {
      const double a = 1.5 * i / 39, r = 0.4 + 0.05 * (i % 5);
      scan.points.push_back({float(o + r * std::cos(a)), float(o + r * std::sin(a)), 0.0f});
    }
    scans.push_back(scan);
  }
  return scans;
}

std::unique_ptr<MappingMethod> build_two_far_scans(const std::string& mode) {
  MethodParams mp;
  mp.set("gp-mode", mode);
  mp.set("gp-length", 0.3);
  auto method = make_method("gpom", testing::small_planar_params(), mp, cpu_backend());
  for (const Scan& scan : two_far_scans()) method->insert(scan);
  method->finish();
  return method;
}

// The learned hyper-parameters, as the backend description prints them.
GpHyperParams learned_of(const MappingMethod& method) {
  const std::string d = method.backend().device;
  GpHyperParams hp;
  hp.covariance = GpCovariance::kNeuralNetwork;
  const size_t at = d.find("S = diag(");
  EXPECT_NE(at, std::string::npos) << d;
  std::sscanf(d.c_str() + at, "S = diag(%lg, %lg, %lg, %lg), signal variance %lg, noise %lg", &hp.nn_sigma[0],
              &hp.nn_sigma[1], &hp.nn_sigma[2], &hp.nn_sigma[3], &hp.signal_var, &hp.noise_std);
  return hp;
}

// Distance from q to the nearest hit or free segment of the scans (each beam from its origin to
// 0.05 m short of its hit, small_planar_params' end margin).
double nearest_datum(const std::vector<ScanObservations>& scans, const Vec3d& q) {
  double best = INFINITY;
  for (const ScanObservations& obs : scans) {
    for (size_t i = 0; i < obs.hits.size(); ++i) {
      const Vec3f& h = obs.hits[i];
      best = std::min(best, std::hypot(h.x - q.x, h.y - q.y));
      const Vec3d o{obs.origin.x, obs.origin.y, 0}, e{obs.free_ends[i].x, obs.free_ends[i].y, 0};
      const Vec3d d{e.x - o.x, e.y - o.y, 0};
      const double t = std::clamp(((q.x - o.x) * d.x + (q.y - o.y) * d.y) / (d.x * d.x + d.y * d.y), 0.0, 1.0);
      best = std::min(best, std::hypot(o.x + t * d.x - q.x, o.y + t * d.y - q.y));
    }
  }
  return best;
}

TEST(GpomPaperMode, CellsNoDatumReachesAreTheGpPriorAndTheExtentIsMapped) {
  const auto method = build_two_far_scans("paper");
  const GpHyperParams hp = learned_of(*method);
  const std::vector<ScanObservations> obs = testing::observations_of(two_far_scans(), testing::small_planar_params());
  // Every cell of the plane in the four blocks of the data's box (grown by 0.3 m) is mapped, none
  // beyond; the cells farther than 0.3 m from every datum are at the prior: mean 0, variance k(q, q).
  int prior = 0;
  for (int cy = 0; cy < 64; ++cy)
    for (int cx = 0; cx < 64; ++cx) {
      const Vec3d q{(cx + 0.5) * 0.1, (cy + 0.5) * 0.1, 0.0};
      const std::optional<CellEstimate> e = method->estimate(q.x, q.y, 0.0);
      ASSERT_TRUE(e.has_value()) << cx << "," << cy;
      if (nearest_datum(obs, q) < 0.3 + 1e-6) continue;
      EXPECT_EQ(*e->gp_mean, 0.0) << cx << "," << cy;
      EXPECT_NEAR(*e->variance, eq7(q, q, hp.nn_sigma, hp.signal_var), 1e-4 * *e->variance) << cx << "," << cy;
      ++prior;
    }
  EXPECT_GT(prior, 3500);  // the far block (1, 0) alone holds 1024
  EXPECT_EQ(method->known_cells(), 64u * 64u);
  EXPECT_FALSE(method->estimate(7.0, 7.0, 0.0).has_value());  // outside the extent
  EXPECT_FALSE(method->estimate(-0.5, 0.5, 0.0).has_value());
  // Near the data, the GP: occupied at a return, free on the beams.
  EXPECT_GT(*method->occupancy(0.5 + 0.4, 0.5, 0.0), 0.5);
  EXPECT_LT(*method->occupancy(0.65, 0.6, 0.0), 0.5);
}

TEST(GpomPaperMode, LocalModelsHoldFifteenHitsAndFifteenBeams) {
  const std::vector<ScanObservations> obs = testing::observations_of(two_far_scans(), testing::small_planar_params());
  uint64_t within_low = 0, within_high = 0;  // the cells within reach, allowing for rounding at 0.3 m
  for (int cy = 0; cy < 64; ++cy)
    for (int cx = 0; cx < 64; ++cx) {
      const double d = nearest_datum(obs, {(cx + 0.5) * 0.1, (cy + 0.5) * 0.1, 0.0});
      within_low += d < 0.3 - 1e-6;
      within_high += d < 0.3 + 1e-6;
    }
  // Each solved cell's local model: 15 hits and 15 beams in paper mode, 30 and 30 by default.
  const auto paper = build_two_far_scans("paper");
  const uint64_t paper_pairs = paper->counts().integrate.pairs_evaluated;
  EXPECT_EQ(paper_pairs % 30, 0u);
  EXPECT_GE(paper_pairs / 30, within_low);
  EXPECT_LE(paper_pairs / 30, within_high);
  const auto plain = build_two_far_scans("default");
  const uint64_t plain_pairs = plain->counts().integrate.pairs_evaluated;
  EXPECT_EQ(plain_pairs, 60 * plain->known_cells());
  EXPECT_EQ(plain_pairs / 60, paper_pairs / 30);  // the same cells solved
}

TEST(GpomPaperMode, RefusesWhatWouldChangeItsCovariance) {
  MethodParams mp;
  mp.set("gp-mode", "paper");
  mp.set("gp-covariance", "se");
  try {
    make_method("gpom", testing::small_planar_params(), mp, cpu_backend());
    FAIL() << "no refusal";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--gp-mode paper"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--gp-covariance se"), std::string::npos) << e.what();
  }
  mp.set("gp-covariance", "matern");
  mp.set("gp-hyperparameters", "learn");
  EXPECT_THROW(make_method("gpom", testing::small_planar_params(), mp, cpu_backend()), std::invalid_argument);
}

}  // namespace
}  // namespace bgkmap
