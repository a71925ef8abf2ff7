// --method bhm: the variational update against a dense implementation written out here, the
// sequential model's algebra, its predictive probabilities and variances, 2-D / 3-D scans, and the
// command end to end on simulated data.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "bgkmap/io/errors.hpp"
#include "bgkmap/methods/method.hpp"
#include "methods/bhm_model.hpp"
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

TEST(BhmModel, RefusesBadParameters) {
  BhmParams p = tiny_params();
  p.block_side = 65;  // 4225 supports per block
  EXPECT_THROW(BhmModel{p}, std::invalid_argument);
  p = tiny_params();
  p.gamma = 0;
  EXPECT_THROW(BhmModel{p}, std::invalid_argument);
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

std::unique_ptr<MappingMethod> bhm_method(double resolution_m, int threads) {
  BuildParams params;
  params.grid.resolution_m = resolution_m;
  BackendOptions backend;
  backend.backend = "cpu";
  backend.threads = threads;
  return make_method("bhm", params, MethodParams{}, backend);
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

// ---------------------------------------------------------------------------------------------
// The command: simulate planar scans, build with bhm (.ot and .bt, the report), score the map.

testing::CommandResult run(const std::string& args) {
  return testing::run_command(std::string(BGKMAP_CLI) + " " + args);
}

TEST(BhmCli, BuildsSimulatedPlanarScansAndEvalScoresThem) {
  const std::filesystem::path dir = testing::make_temp_dir("bhm_cli");
  const std::string d = dir.string();
  testing::CommandResult r = run("simulate structured -o " + d + "/sim --sensor planar --scans 4 -q");
  ASSERT_EQ(r.status, 0) << r.output;
  r = run("build -q --method bhm " + d + "/sim/scans -o " + d + "/m.ot -o " + d + "/m.bt --report " + d +
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
  // .bgk is refused before any work.
  r = run("build -q --method bhm " + d + "/sim/scans -o " + d + "/m.bgk");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("m.bgk"), std::string::npos) << r.output;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap
