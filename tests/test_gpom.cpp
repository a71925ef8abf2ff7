// --method gpom against plain references: the Matern covariance, leave-one-out predictions against
// refitting without each point, the PLSC likelihood's gradient against finite differences and its
// fit against known parameters, and the whole map against an exact dense GP per cell (every
// hit and beam in the local model), in double precision.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/methods/method.hpp"
#include "methods/gp_regression.hpp"
#include "methods/plsc.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

using testing::cpu_backend;

// Exact GP posterior by Gauss-Jordan on the full system (no Cholesky, no Eigen): the reference.
GpPrediction dense_gp(const std::vector<Vec3d>& x, const std::vector<double>& y, const Vec3d& q, const GpHyperParams& hp) {
  const size_t n = x.size();
  const auto dist = [](const Vec3d& a, const Vec3d& b) {
    return std::sqrt((a.x - b.x) * (a.x - b.x) + (a.y - b.y) * (a.y - b.y) + (a.z - b.z) * (a.z - b.z));
  };
  // [K + sn^2 I | y | k*]: solve both right-hand sides.
  std::vector<std::vector<double>> m(n, std::vector<double>(n + 2));
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = 0; j < n; ++j) m[i][j] = gp_kernel(dist(x[i], x[j]), hp) + (i == j ? hp.noise_std * hp.noise_std : 0);
    m[i][n] = y[i];
    m[i][n + 1] = gp_kernel(dist(x[i], q), hp);
  }
  for (size_t c = 0; c < n; ++c) {
    size_t pivot = c;
    for (size_t r = c + 1; r < n; ++r)
      if (std::abs(m[r][c]) > std::abs(m[pivot][c])) pivot = r;
    std::swap(m[c], m[pivot]);
    for (size_t r = 0; r < n; ++r) {
      if (r == c) continue;
      const double f = m[r][c] / m[c][c];
      for (size_t k = c; k < n + 2; ++k) m[r][k] -= f * m[c][k];
    }
  }
  GpPrediction p;
  p.variance = gp_kernel(0, hp);
  for (size_t i = 0; i < n; ++i) {
    const double ks = gp_kernel(dist(x[i], q), hp);
    p.mean += ks * m[i][n] / m[i][i];
    p.variance -= ks * m[i][n + 1] / m[i][i];
  }
  return p;
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

std::vector<Vec3d> random_points(std::mt19937& rng, int n, double extent) {
  std::uniform_real_distribution<double> u(0, extent);
  std::vector<Vec3d> out(n);
  for (Vec3d& p : out) p = {u(rng), u(rng), u(rng)};
  return out;
}

TEST(GpomLeaveOneOut, EqualsRefittingWithoutEachPoint) {
  std::mt19937 rng(3);
  for (const GpCovariance covariance : {GpCovariance::kMatern32, GpCovariance::kSparse}) {
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

TEST(GpomRegression, GpPredictWithMaternEqualsTheDenseReference) {
  std::mt19937 rng(4);
  GpHyperParams hp;
  hp.covariance = GpCovariance::kMatern32;
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
TEST(GpomMethod, EqualsTheDenseGpPerCellWithAllDataIn2D) {
  BuildParams params;
  params.grid.resolution_m = 0.1;
  params.grid.block_depth = 6;
  params.preprocess.max_range_m = 0;
  params.preprocess.end_margin_m = 0.05f;
  MethodParams mp;
  mp.gp_length_m = 0.3;
  mp.gp_signal_var = 1.0;
  mp.gp_noise = 0.1;
  Scan scan;
  scan.pose.position = {1.62f, 1.55f, 0.0f};
  for (int i = 0; i < 12; ++i) {
    const double a = 0.5 * i, r = 0.4 + 0.05 * (i % 5);
    scan.points.push_back({static_cast<float>(1.62 + r * std::cos(a)), static_cast<float>(1.55 + r * std::sin(a)), 0.0f});
  }
  auto method = make_method("gpom", params, mp, cpu_backend());
  method->insert(scan);
  method->finish();

  ScanObservations obs;
  PreprocessCounts counts;
  preprocess_scan(scan, params.preprocess, obs, counts);
  ASSERT_EQ(obs.hits.size(), 12u);
  ASSERT_EQ(obs.free_ends.size(), 12u);
  GpHyperParams hp;
  hp.covariance = GpCovariance::kMatern32;
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
      const GpPrediction ref = dense_gp(x, y, q, hp);
      EXPECT_NEAR(*e->gp_mean, ref.mean, 1e-9) << cx << "," << cy;
      EXPECT_NEAR(*e->variance, ref.variance, 1e-9) << cx << "," << cy;
      expected.push_back({q, ref});
      if (evaluated++ % 64 == 0) {
        const std::vector<GpPrediction> loo = gp_leave_one_out(x, y, hp);
        for (size_t i = 0; i < loo.size(); ++i) pool.push_back({y[i], loo[i].mean, loo[i].variance});
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

// k below the data: the local model holds the k nearest hits (found by the k-d tree) and the
// nearest points of the k nearest beams (here every beam is one sample: all are candidates).
TEST(GpomMethod, LocalModelHoldsTheKNearestHitsIn3D) {
  BuildParams params;
  params.grid.resolution_m = 0.1;
  params.preprocess.max_range_m = 0;
  params.preprocess.end_margin_m = 0;
  MethodParams mp;
  mp.gp_neighbours = 3;
  mp.gp_length_m = 1.2;  // beam samples 0.6 m apart: one per beam, ten in all, fewer than 4k
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

// Build and held-out evaluation through the command line on a simulated planar scene.
TEST(GpomCli, HoldoutOnASimulatedPlanarScene) {
  const auto dir = testing::make_temp_dir("gpom-cli");
  const std::string cli = std::string(BGKMAP_CLI) + " ", d = dir.string() + "/";
  ASSERT_EQ(testing::run_command(cli + "simulate structured --sensor planar --scans 4 -q --truth-resolution 0 -o " + d + "sim").status, 0);
  const auto r = testing::run_command(cli + "eval --holdout 0.2 --seed 1 " + d + "sim/scans --method gpom --max-range 8 "
                                      "--resolution 0.1 --gp-length 0.5 --threads 2 --json " + d + "e.json");
  ASSERT_EQ(r.status, 0) << r.output;
  std::ifstream in(d + "e.json");
  const nlohmann::json e = nlohmann::json::parse(in);
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

}  // namespace
}  // namespace bgkmap
