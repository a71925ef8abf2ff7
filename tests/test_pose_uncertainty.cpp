// Pose uncertainty: the sigma points, the expected sub-map and the expected kernel on the CPU path
// against their brute force (double precision over the same sigma points), the moment matching,
// zero covariance as plain BGK-L bit for bit, the poses files with covariance, and the
// simulator's odometry drift.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <random>
#include <utility>

#include "bgkmap/core/pose_covariance.hpp"
#include "bgkmap/integrate/cpu_integrator.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/pose_list.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "bgkmap/map/expected_submap.hpp"
#include "bgkmap/mapper.hpp"
#include "bgkmap/methods/method.hpp"
#include "bgkmap/sim/presets.hpp"
#include "bgkmap/sim/simulate.hpp"
#include "integrate/brute_force.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

// A random covariance of rank `rank` over the six axes: A A^T, A 6 x rank, entries scaled by
// `translation_m` (rows 0-2) and `rotation_rad` (rows 3-5).
PoseCovariance random_covariance(std::mt19937& rng, int rank, double translation_m, double rotation_rad) {
  std::normal_distribution<double> n(0.0, 1.0);
  double a[6][6] = {};
  for (int i = 0; i < 6; ++i)
    for (int k = 0; k < rank; ++k) a[i][k] = n(rng) * (i < 3 ? translation_m : rotation_rad);
  PoseCovariance c;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j)
      for (int k = 0; k < rank; ++k) c(i, j) += a[i][k] * a[j][k];
  return c;
}

TEST(PoseSigmaPoints, ReproduceMeanAndCovariance) {
  std::mt19937 rng(7);
  for (int rank : {1, 3, 6}) {
    const PoseCovariance c = random_covariance(rng, rank, 0.1, 0.05);
    ASSERT_EQ(pose_covariance_problem(c), "");
    const std::vector<PoseSigmaPoint> points = pose_sigma_points(c);
    ASSERT_EQ(points.size(), static_cast<size_t>(2 * rank)) << "rank " << rank;
    double weights = 0, mean[6] = {}, cov[6][6] = {};
    for (const PoseSigmaPoint& p : points) {
      EXPECT_GT(p.weight, 0);
      const double d[6] = {p.translation.x, p.translation.y, p.translation.z, p.rotation.x, p.rotation.y, p.rotation.z};
      weights += p.weight;
      for (int i = 0; i < 6; ++i) {
        mean[i] += p.weight * d[i];
        for (int j = 0; j < 6; ++j) cov[i][j] += p.weight * d[i] * d[j];
      }
    }
    EXPECT_NEAR(weights, 1.0, 1e-15);
    for (int i = 0; i < 6; ++i) {
      EXPECT_NEAR(mean[i], 0.0, 1e-15);
      for (int j = 0; j < 6; ++j) EXPECT_NEAR(cov[i][j], c(i, j), 1e-12) << rank << " " << i << " " << j;
    }
  }
  EXPECT_TRUE(pose_sigma_points(PoseCovariance{}).empty());
  // The planar form lands on x, y and yaw.
  const PoseCovariance planar = PoseCovariance::from_planar({0.04, 0.01, 0, 0.01, 0.09, 0, 0, 0, 0.0025});
  EXPECT_EQ(planar(0, 0), 0.04);
  EXPECT_EQ(planar(1, 0), 0.01);
  EXPECT_EQ(planar(5, 5), 0.0025);
  EXPECT_EQ(pose_sigma_points(planar).size(), 6u);
}

TEST(PoseSigmaPoints, RefusesWhatIsNotACovariance) {
  PoseCovariance c = PoseCovariance::from_sigma({0.1, 0.01, 0, 0});
  c(0, 0) = -0.01;
  EXPECT_EQ(pose_covariance_problem(c), "not positive semi-definite");
  c = PoseCovariance::from_sigma({0.1, 0.01, 0, 0});
  c(0, 1) = 0.5;  // |c01| > sqrt(c00 c11): indefinite
  c(1, 0) = 0.5;
  EXPECT_EQ(pose_covariance_problem(c), "not positive semi-definite");
  c(1, 0) = 0.4;
  EXPECT_EQ(pose_covariance_problem(c), "not symmetric");
  c(1, 0) = std::nan("");
  EXPECT_EQ(pose_covariance_problem(c), "not finite");
}

// The covariance of the sigma points, entry by entry, within `tol` of sqrt(c_ii c_jj).
void expect_points_reproduce(const std::vector<PoseSigmaPoint>& points, const PoseCovariance& c, double tol,
                             const std::string& what) {
  double cov[6][6] = {};
  for (const PoseSigmaPoint& p : points) {
    const double d[6] = {p.translation.x, p.translation.y, p.translation.z, p.rotation.x, p.rotation.y, p.rotation.z};
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j < 6; ++j) cov[i][j] += p.weight * d[i] * d[j];
  }
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j)
      EXPECT_NEAR(cov[i][j], c(i, j), tol * std::sqrt(c(i, i) * c(j, j))) << what << " " << i << " " << j;
}

// Standard deviations beyond the key range (translation) or pi (rotation) cannot be meant: refused
// by name, before anything squares or factors them; up to the bounds they are taken, finite.
TEST(PoseSigmaPoints, RefusesUncertaintiesThatCannotBeMeant) {
  const double t = kMaxPoseTranslationSigmaM, r = kMaxPoseRotationSigmaRad;
  EXPECT_EQ(t, 1e6);
  PoseCovariance c = PoseCovariance::from_sigma({t, r, t, r});
  EXPECT_EQ(pose_covariance_problem(c), "");
  const std::vector<PoseSigmaPoint> points = pose_sigma_points(c);
  ASSERT_EQ(points.size(), 12u);
  expect_points_reproduce(points, c, 1e-12, "at the bounds");
  const char* const axes[6] = {"x", "y", "z", "roll", "pitch", "yaw"};
  for (int i = 0; i < 6; ++i) {
    c = PoseCovariance::from_sigma({0.1, 0.01, 0.1, 0.01});
    const double sd = (i < 3 ? t : r) * 1.001;
    c(i, i) = sd * sd;
    const std::string problem = pose_covariance_problem(c);
    EXPECT_EQ(problem.rfind(std::string("too large to be meant: ") + axes[i] + "'s standard deviation ", 0), 0u) << problem;
    EXPECT_THROW(pose_sigma_points(c), std::invalid_argument);
  }
  c = PoseCovariance::from_planar({1e80, 0, 0, 0, 1e80, 0, 0, 0, 1e80});
  EXPECT_EQ(pose_covariance_problem(c),
            "too large to be meant: x's standard deviation 1e+40 m is beyond the map's key range (at most 1e+06 m)");
  // An off-diagonal entry no pair of variances can hold, however large, is refused, not overflowed.
  c = PoseCovariance::from_sigma({0.1, 0.01, 0, 0});
  c(0, 5) = c(5, 0) = 1e300;
  EXPECT_EQ(pose_covariance_problem(c), "not positive semi-definite");
  c(0, 5) = c(5, 0) = 0;
  c(2, 0) = c(0, 2) = 1e-6;  // z has no variance, so it can have no covariance (beyond rounding)
  EXPECT_EQ(pose_covariance_problem(c), "not positive semi-definite");

  // Constant standard deviations: checked before squaring (1e155 squares to inf), named.
  for (const char* bad : {"1e40,0", "1e155,0", "0,1e155", "1e300,1", "1e10,0", "0,3.2", "0.1,0.01,2e6,0", "0.1,0.01,0,4"}) {
    try {
      parse_pose_sigma(bad, "--pose-sigma");
      ADD_FAILURE() << "accepted " << bad;
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()).rfind("--pose-sigma '" + std::string(bad) + "': too large to be meant: ", 0), 0u)
          << e.what();
    }
  }
  try {
    parse_pose_sigma("1e40,0", "--pose-sigma");
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "--pose-sigma '1e40,0': too large to be meant: x and y's standard deviation 1e+40 m is "
                           "beyond the map's key range (at most 1e+06 m)");
  }
  for (const char* good : {"1e6,0", "0,3.14159", "0.1,0.01,1e6,3.14159"}) EXPECT_NO_THROW(parse_pose_sigma(good)) << good;
  // The parameters say the same (a map's header, the library).
  BuildParams params = testing::small_params();
  params.preprocess.pose_sigma = {1e155, 0, 0, 0};
  try {
    params.validate();
    ADD_FAILURE() << "a pose sigma of 1e155 m validated";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("pose-sigma: too large to be meant: x and y's standard deviation 1e+155 m"),
              std::string::npos)
        << e.what();
  }
  params.preprocess.pose_sigma = {0.1, 0.01, 0, 0};
  EXPECT_NO_THROW(params.validate());
}

// Covariances written by other tools are rounded: a correlation of 1 printed with 7 digits may read
// 1.0000001, and the two triangles may differ in their last digit. Taken as the rank-deficient
// covariances they are (within kPoseCovarianceTolerance of each axis's scale); real violations
// (a correlation of 1.01) are still refused.
TEST(PoseSigmaPoints, TakesCovariancesRoundedByOtherTools) {
  PoseCovariance c = PoseCovariance::from_planar({1e-4, 1.0000001e-4, 0, 1.0000001e-4, 1e-4, 0, 0, 0, 4e-6});
  EXPECT_EQ(pose_covariance_problem(c), "");
  std::vector<PoseSigmaPoint> points = pose_sigma_points(c);
  EXPECT_EQ(points.size(), 4u);  // x and y move together: rank 2
  expect_points_reproduce(points, c, 1e-6, "x = y");
  c = PoseCovariance::from_planar({1e-4, 1.01e-4, 0, 1.01e-4, 1e-4, 0, 0, 0, 4e-6});
  EXPECT_EQ(pose_covariance_problem(c), "not positive semi-definite");
  c = PoseCovariance::from_planar({1e-4, 0.9999e-4, 0, 1.0001e-4, 1e-4, 0, 0, 0, 4e-6});
  EXPECT_EQ(pose_covariance_problem(c), "not symmetric");

  // Random covariances of every rank over metres and milliradians, each entry printed with 7
  // significant digits (the lower triangle from a copy 1e-7 off, as another product would be).
  std::mt19937 rng(11);
  for (int rank = 1; rank <= 6; ++rank)
    for (int trial = 0; trial < 20; ++trial) {
      const PoseCovariance exact = random_covariance(rng, rank, 0.1, 0.002);
      PoseCovariance printed;
      for (int i = 0; i < 6; ++i)
        for (int j = 0; j < 6; ++j) {
          char text[32];
          std::snprintf(text, sizeof text, "%.7g", exact(i, j) * (i > j ? 1 + 1e-7 : 1));
          printed(i, j) = std::strtod(text, nullptr);
        }
      const std::string what = "rank " + std::to_string(rank) + " trial " + std::to_string(trial);
      ASSERT_EQ(pose_covariance_problem(printed), "") << what;
      points = pose_sigma_points(printed);
      EXPECT_EQ(points.size(), static_cast<size_t>(2 * rank)) << what;
      expect_points_reproduce(points, exact, 1e-5, what);
    }
  // The tolerance is each axis's own: a yaw of 1e-7 rad beside metres of translation is an axis.
  c = PoseCovariance::from_sigma({1, 1e-7, 0, 0});
  EXPECT_EQ(pose_sigma_points(c).size(), 6u);
  // A variance printed as 0 beside its covariances' rounding (1e-20 next to 1e-2) is taken as 0;
  // a covariance of that axis as large as the others' is not.
  c = PoseCovariance::from_sigma({0.1, 0.01, 0, 0.01});
  c(0, 2) = c(2, 0) = 1e-20;
  EXPECT_EQ(pose_covariance_problem(c), "");
  EXPECT_EQ(pose_sigma_points(c).size(), 10u);  // z has no variance: rank 5
  c(0, 2) = c(2, 0) = 1e-3;
  EXPECT_EQ(pose_covariance_problem(c), "not positive semi-definite");
}

TEST(PoseSigma, ParsesTwoOrFourValues) {
  const PoseSigma a = parse_pose_sigma("0.05,0.01");
  EXPECT_EQ(a.xy_m, 0.05);
  EXPECT_EQ(a.yaw_rad, 0.01);
  EXPECT_EQ(a.z_m, 0);
  const PoseSigma b = parse_pose_sigma("0.05,0.01,0.02,0.003");
  EXPECT_EQ(b.z_m, 0.02);
  EXPECT_EQ(b.roll_pitch_rad, 0.003);
  for (const char* bad : {"", "0.1", "0.1,0.2,0.3", "0.1,x", "-0.1,0.2", "0.1,inf", "0.1,,0.2,0.3"})
    EXPECT_THROW(parse_pose_sigma(bad), std::invalid_argument) << bad;
}

using testing::small_params;

// Every cell of every block within kRelTol of the brute force (and 1e-9 sigma0 absolute, for
// cells whose sums are a few pairs near l: the displaced observations are rounded to float
// before the back end sees them, the brute force keeps them in double).
constexpr double kRelTol = 2e-5;
// The map's fusion (PoseFusion) picks the reference.
void expect_matches_expected_brute_force(const BgkMap& map, const std::vector<ScanObservations>& obs,
                                         const std::vector<PoseCovariance>& covariances) {
  const Grid& grid = map.grid();
  const bool submap = map.params().preprocess.pose_fusion == PoseFusion::kExpectedSubmap;
  const double abs_tol = 1e-9 * map.params().kernel.sigma0;
  std::vector<Vec3d> centers;
  std::vector<Cell> cells;
  for (uint32_t slot = 0; slot < map.block_count(); ++slot) {
    const BlockKey key = map.key_of_slot(slot);
    for (int local = 0; local < grid.cells_per_block(); ++local) {
      const CellIndex ci = grid.cell_at(key, local);
      if (map.params().preprocess.planar && ci.z != map.params().planar_layer()) continue;
      centers.push_back(grid.cell_center_d(ci));
      cells.push_back(map.block_cells(slot)[local]);
    }
  }
  const std::vector<BruteForcePosterior> refs =
      submap ? brute_force_expected_submap_cells(centers, obs, covariances, map.params())
             : brute_force_expected_cells(centers, obs, covariances, map.params());
  size_t with_evidence = 0;
  double worst_rel = 0, worst_abs = 0;
  for (size_t i = 0; i < centers.size(); ++i) {
    const Vec3d& c = centers[i];
    const BruteForcePosterior& ref = refs[i];
    ASSERT_NEAR(cells[i].alpha, ref.alpha, kRelTol * ref.alpha + abs_tol) << c.x << "," << c.y << "," << c.z;
    ASSERT_NEAR(cells[i].beta, ref.beta, kRelTol * ref.beta + abs_tol) << c.x << "," << c.y << "," << c.z;
    with_evidence += ref.alpha > map.params().prior.alpha0 || ref.beta > map.params().prior.beta0;
    for (const auto& [got, want] : {std::pair<double, double>{cells[i].alpha, ref.alpha}, {cells[i].beta, ref.beta}}) {
      worst_abs = std::max(worst_abs, std::abs(got - want));
      worst_rel = std::max(worst_rel, std::abs(got - want) / want);
    }
  }
  EXPECT_GT(with_evidence, centers.size() / 10);
  std::printf("  %zu cells (%zu with evidence): worst difference %.3g relative, %.3g sigma0 absolute\n", centers.size(),
              with_evidence, worst_rel, worst_abs / map.params().kernel.sigma0);
}

// Both fusions on the CPU path against their brute force: full-rank, planar and zero
// covariances in one map, 8^3 and 4^3 blocks.
void expect_cpu_equals_brute_force(PoseFusion fusion) {
  for (uint32_t seed : {1u, 2u, 3u}) {
    BuildParams params = small_params();
    params.preprocess.pose_fusion = fusion;
    params.grid.block_depth = seed == 3 ? 4 : 3;  // 8^3 blocks (the AVX-512 beams where there) and 4^3
    std::vector<Scan> scans = testing::random_scans(seed, 3, 60, 1.5f);
    std::mt19937 rng(seed);
    std::vector<PoseCovariance> covariances;
    for (size_t i = 0; i < scans.size(); ++i) {
      // Full rank, planar (x, y, yaw) and zero: a zero covariance adds the plain kernel.
      covariances.push_back(i == 0 ? random_covariance(rng, 6, 0.05, 0.02)
                            : i == 1 ? PoseCovariance::from_planar({0.01, 0.002, 0, 0.002, 0.004, 0.0005, 0, 0.0005, 0.001})
                                     : PoseCovariance{});
      scans[i].pose_covariance = covariances.back();
    }
    Mapper mapper(params, std::make_unique<CpuIntegrator>(2));
    for (const Scan& s : scans) mapper.insert(s);
    expect_matches_expected_brute_force(mapper.map(), testing::observations_of(scans, params), covariances);
    EXPECT_EQ(mapper.counts().scans, scans.size());
  }
}

TEST(ExpectedKernel, CpuEqualsBruteForceOverTheSigmaPoints) { expect_cpu_equals_brute_force(PoseFusion::kExpectedKernel); }

TEST(ExpectedSubmap, CpuEqualsBruteForceOverTheSigmaPoints) { expect_cpu_equals_brute_force(PoseFusion::kExpectedSubmap); }

// Worked by hand: Beta(1, 1) and Beta(3, 1), half each: E[p] = (1/2 + 3/4) / 2 = 0.625,
// E[p^2] = (1/3 + 3/5) / 2 = 7/15, so s = (E[p] - E[p^2]) / (E[p^2] - E[p]^2) = 0.158333 / 0.0760417.
TEST(ExpectedSubmap, MomentMatchingByHand) {
  const double s = (0.625 - 7.0 / 15.0) / (7.0 / 15.0 - 0.625 * 0.625);
  BetaParams b = moment_matched_beta({{1, 1}, {3, 1}}, {0.5, 0.5});
  EXPECT_NEAR(b.alpha, 0.625 * s, 1e-12);
  EXPECT_NEAR(b.beta, 0.375 * s, 1e-12);
  EXPECT_NEAR(b.alpha, 1.3013698630136987, 1e-12);  // s = 2.0821917808219177
  // One component, or equal ones: that Beta again.
  b = moment_matched_beta({{2, 5}, {2, 5}, {2, 5}}, {0.2, 0.3, 0.5});
  EXPECT_NEAR(b.alpha, 2.0, 1e-12);
  EXPECT_NEAR(b.beta, 5.0, 1e-12);
  // Disagreeing sigma points make a weak Beta: half sure of occupied, half sure of free.
  b = moment_matched_beta({{50, 0.001}, {0.001, 50}}, {0.5, 0.5});
  EXPECT_NEAR(b.alpha / (b.alpha + b.beta), 0.5, 1e-12);
  EXPECT_LT(b.alpha + b.beta, 0.03);
}

// A cell that every sigma point leaves at the prior keeps its bits; cells reached by few points
// get little evidence, and the scan never takes evidence away.
TEST(ExpectedSubmap, AddsNonNegativeCountsAndLeavesUnreachedCells) {
  BuildParams params = small_params();
  const std::vector<Scan> scans = testing::random_scans(21, 2, 150, 1.5f);
  Mapper before(params, std::make_unique<CpuIntegrator>(2));
  before.insert(scans[0]);
  Mapper after(params, std::make_unique<CpuIntegrator>(2));
  after.insert(scans[0]);
  Scan uncertain = scans[1];
  uncertain.pose_covariance = PoseCovariance::from_sigma({0.1, 0.05, 0, 0});
  after.insert(uncertain);
  const BgkMap& a = before.map();
  const BgkMap& b = after.map();
  size_t unchanged = 0, grew = 0;
  for (uint32_t slot = 0; slot < a.block_count(); ++slot) {
    const int64_t other = b.find_slot(a.key_of_slot(slot));
    ASSERT_GE(other, 0);
    for (int i = 0; i < a.cells_per_block(); ++i) {
      const Cell& x = a.block_cells(slot)[i];
      const Cell& y = b.block_cells(static_cast<uint32_t>(other))[i];
      ASSERT_GE(y.alpha, x.alpha);
      ASSERT_GE(y.beta, x.beta);
      if (y.alpha == x.alpha && y.beta == x.beta) ++unchanged;
      else ++grew;
    }
  }
  EXPECT_GT(unchanged, 0u);
  EXPECT_GT(grew, 0u);
}

TEST(PoseUncertainty, ConstantPoseSigmaIsEveryScansCovariance) {
  for (PoseFusion fusion : {PoseFusion::kExpectedSubmap, PoseFusion::kExpectedKernel}) {
    BuildParams params = small_params();
    params.preprocess.pose_fusion = fusion;
    params.preprocess.pose_sigma = {0.04, 0.03, 0.02, 0.01};
    const std::vector<Scan> scans = testing::random_scans(5, 2, 100, 1.5f);
    Mapper mapper(params, std::make_unique<CpuIntegrator>(2));
    for (const Scan& s : scans) mapper.insert(s);
    const std::vector<PoseCovariance> covariances(scans.size(), PoseCovariance::from_sigma(params.preprocess.pose_sigma));
    expect_matches_expected_brute_force(mapper.map(), testing::observations_of(scans, params), covariances);
  }
}

TEST(PoseUncertainty, PlanarMapKeepsThePlane) {
  for (PoseFusion fusion : {PoseFusion::kExpectedSubmap, PoseFusion::kExpectedKernel}) {
    BuildParams params = small_params();
    params.preprocess.pose_fusion = fusion;
    params.grid.block_depth = 4;
    params.set_planar(0.0);
    std::vector<Scan> scans = testing::random_scans(9, 3, 150, 1.5f);
    std::vector<PoseCovariance> covariances;
    for (Scan& s : scans) {
      // Roll and pitch too: their out-of-plane part is dropped, the in-plane part kept.
      s.pose_covariance = PoseCovariance::from_sigma({0.03, 0.02, 0.05, 0.01});
      covariances.push_back(*s.pose_covariance);
    }
    Mapper mapper(params, std::make_unique<CpuIntegrator>(2));
    for (const Scan& s : scans) mapper.insert(s);
    expect_matches_expected_brute_force(mapper.map(), testing::observations_of(scans, params), covariances);
  }
}

// Byte for byte: the pool of cells and the block keys.
void expect_same_maps(const BgkMap& a, const BgkMap& b) {
  ASSERT_EQ(a.block_count(), b.block_count());
  for (uint32_t slot = 0; slot < a.block_count(); ++slot) {
    ASSERT_EQ(a.key_of_slot(slot), b.key_of_slot(slot));
    ASSERT_EQ(std::memcmp(a.block_cells(slot), b.block_cells(slot), sizeof(Cell) * a.cells_per_block()), 0) << slot;
  }
}

TEST(PoseUncertainty, ZeroCovarianceIsPlainBgkLBitForBit) {
  for (int depth : {3, 4}) {
    BuildParams params = small_params();
    params.grid.block_depth = depth;
    std::vector<Scan> scans = testing::random_scans(11, 4, 200, 1.5f);
    Mapper plain(params, std::make_unique<CpuIntegrator>(2));
    for (const Scan& s : scans) plain.insert(s);
    Mapper zero(params, std::make_unique<CpuIntegrator>(2));
    for (Scan s : scans) {
      s.pose_covariance = PoseCovariance{};
      zero.insert(s);
    }
    expect_same_maps(plain.map(), zero.map());
    // And a tiny covariance does change it: the path above did take the zero branch.
    Mapper tiny(params, std::make_unique<CpuIntegrator>(2));
    for (Scan s : scans) {
      s.pose_covariance = PoseCovariance::from_sigma({1e-3, 0, 0, 0});
      tiny.insert(s);
    }
    EXPECT_NE(std::memcmp(plain.map().block_cells(0), tiny.map().block_cells(0), sizeof(Cell) * plain.map().cells_per_block()), 0);
  }
}

TEST(ExpectedKernel, BoxKernelAndMethodsWithoutItAreRefused) {
  BuildParams params = small_params();
  params.kernel.type = KernelType::kBox;
  params.preprocess.pose_sigma = {0.1, 0.01, 0, 0};
  EXPECT_THROW(params.validate(), std::invalid_argument);
  params = small_params();
  params.preprocess.pose_sigma = {0.1, 0.01, 0, 0};
  EXPECT_THROW(make_method("octomap", params, MethodParams{}, testing::cpu_backend()), std::invalid_argument);
  EXPECT_THROW(make_method("counting", params, MethodParams{}, testing::cpu_backend()), std::invalid_argument);
  EXPECT_NO_THROW(make_method("bgk", params, MethodParams{}, testing::cpu_backend()));
  // A scan bringing its own covariance to a method that would ignore it.
  std::unique_ptr<MappingMethod> octomap = make_method("octomap", small_params(), MethodParams{}, testing::cpu_backend());
  Scan scan = testing::random_scans(1, 1, 10, 1.0f)[0];
  scan.pose_covariance = PoseCovariance::from_sigma({0.1, 0.01, 0, 0});
  EXPECT_THROW(octomap->insert(scan), std::invalid_argument);
}

void write_text(const std::filesystem::path& file, const std::string& text) {
  std::ofstream(file) << text;
}

TEST(PoseList, ReadsCovariancesAndNamesBadLines) {
  testing::TempDir dir("pose_list");
  const auto file = dir / "poses.txt";
  write_text(file,
             "# comment\n"
             "0 1 2 3 0 0 0 1\n"
             "0.1 1 2 3 0 0 0 2 0.04 0 0 0 0.04 0 0 0 0.0001\n"
             "0.2 1 2 3 0 0 0 1 " + std::string([] {
               std::string s;
               for (int i = 0; i < 36; ++i) s += (i % 7 == 0 ? "0.01 " : "0 ");
               return s;
             }()) + "\n");
  const std::vector<PoseRecord> poses = read_pose_list(file);
  ASSERT_EQ(poses.size(), 3u);
  EXPECT_FALSE(poses[0].covariance);
  ASSERT_TRUE(poses[1].covariance);
  EXPECT_EQ((*poses[1].covariance)(0, 0), 0.04);
  EXPECT_EQ((*poses[1].covariance)(5, 5), 0.0001);
  EXPECT_EQ((*poses[1].covariance)(2, 2), 0.0);
  EXPECT_FLOAT_EQ(poses[1].pose.qw, 1.0f);
  ASSERT_TRUE(poses[2].covariance);
  EXPECT_EQ((*poses[2].covariance)(3, 3), 0.01);
  EXPECT_EQ(poses[2].line, 4u);

  const std::pair<const char*, const char*> bad[] = {
      {"0 1 2 3 0 0 0 1 0.1\n", "line 1: poses: 9 fields"},
      {"0 1 2 3 0 0 0 1 1 0 0 0 1 0 0 0 nan\n", "line 1: poses: field 17 is not a finite number"},
      {"0 0 0 0 0 0 0 1\n0 1 2 3 0 0 0 1 1 2 0 2 1 0 0 0 1\n", "line 2: poses: the covariance is not positive semi-definite"},
      {"0 1 2 3 0 0 0 1 1 0.5 0 0 1 0 0 0 1\n", "line 1: poses: the covariance is not symmetric"},
      {"0 1 2 3 0 0 0 1 1e80 0 0 0 1e80 0 0 0 1e80\n",
       "line 1: poses: the covariance is too large to be meant: x's standard deviation 1e+40 m is beyond the map's key range"},
      {"0 1 2 3 0 0 0 1 1 0 0 0 1 0 0 0 10\n", "line 1: poses: the covariance is too large to be meant: yaw's standard deviation"},
  };
  // A rank-deficient covariance rounded by the tool that wrote it is no bad line.
  write_text(file, "0 1 2 3 0 0 0 1 1e-4 1.0000001e-4 0 1.0000001e-4 1e-4 0 0 0 4e-6\n");
  const std::vector<PoseRecord> rounded = read_pose_list(file);
  ASSERT_EQ(rounded.size(), 1u);
  EXPECT_EQ(pose_sigma_points(*rounded[0].covariance).size(), 4u);
  for (const auto& [text, message] : bad) {
    write_text(file, text);
    try {
      read_pose_list(file);
      ADD_FAILURE() << "accepted " << text;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(file.string() + ": " + message), std::string::npos) << e.what();
    }
  }
}

TEST(PoseList, CovarianceFileMatchesEveryScanInOrder) {
  testing::TempDir dir("pose_covariance");
  // Two XYZ scans posed by --poses (one with a covariance of its own), covariances for PCD-less inputs.
  write_text(dir / "a.xyz", "1 0 0\n0 1 0\n");
  write_text(dir / "b.xyz", "1 1 0\n");
  write_text(dir / "poses.txt", "0 0 0 0 0 0 0 1\n0 1 0 0 0 0 0 1 0.01 0 0 0 0.01 0 0 0 0.001\n");
  {
    ScanSourceOptions options;
    options.poses = dir / "poses.txt";
    ScanSource source({dir / "a.xyz", dir / "b.xyz"}, options);
    Scan scan;
    ASSERT_TRUE(source.next(scan));
    EXPECT_FALSE(scan.pose_covariance);
    ASSERT_TRUE(source.next(scan));
    ASSERT_TRUE(scan.pose_covariance);
    EXPECT_EQ((*scan.pose_covariance)(5, 5), 0.001);
    EXPECT_EQ(scan.pose_covariance_source, (dir / "poses.txt").string() + " line 2");
  }
  write_text(dir / "plain_poses.txt", "0 0 0 0 0 0 0 1\n0 1 0 0 0 0 0 1\n");
  write_text(dir / "cov.txt", "0 0 0 0 0 0 0 1 0.01 0 0 0 0.01 0 0 0 0.001\n0 1 0 0 0 0 0 1 0.04 0 0 0 0.04 0 0 0 0.002\n");
  ScanSourceOptions options;
  options.poses = dir / "plain_poses.txt";
  options.pose_covariance = dir / "cov.txt";
  {
    const auto scans = [&] {
      ScanSource source({dir / "a.xyz", dir / "b.xyz"}, options);
      std::vector<Scan> out;
      for (Scan s; source.next(s);) out.push_back(s);
      return out;
    }();
    ASSERT_EQ(scans.size(), 2u);
    EXPECT_EQ((*scans[0].pose_covariance)(0, 0), 0.01);
    EXPECT_EQ((*scans[1].pose_covariance)(5, 5), 0.002);
    EXPECT_EQ(scans[1].pose_covariance_source, (dir / "cov.txt").string() + " line 2");
    BuildParams params = small_params();
    EXPECT_EQ(prepare_scan(scans[1], params.preprocess).pose_covariance_source, (dir / "cov.txt").string() + " line 2");
    Scan plain = scans[1];
    plain.pose_covariance.reset();
    params.preprocess.pose_sigma = {0.1, 0.01, 0, 0};
    EXPECT_EQ(prepare_scan(plain, params.preprocess).pose_covariance_source, "--pose-sigma");
  }
  const auto drain = [&](const ScanSourceOptions& o) {
    ScanSource source({dir / "a.xyz", dir / "b.xyz"}, o);
    for (Scan s; source.next(s);) {
    }
  };
  // A line whose position is not its scan's origin; too many lines; too few.
  write_text(dir / "cov.txt", "0 0 0 0 0 0 0 1 0.01 0 0 0 0.01 0 0 0 0.001\n0 1.1 0 0 0 0 0 1 0.01 0 0 0 0.01 0 0 0 0.001\n");
  testing::expect_input_error(dir / "cov.txt", [&] { drain(options); }, "position");
  write_text(dir / "cov.txt", "0 0 0 0 0 0 0 1 0.01 0 0 0 0.01 0 0 0 0.001\n0 1 0 0 0 0 0 1 0.01 0 0 0 0.01 0 0 0 0.001\n"
                              "0 2 0 0 0 0 0 1 0.01 0 0 0 0.01 0 0 0 0.001\n");
  testing::expect_input_error(dir / "cov.txt", [&] { drain(options); }, "too many lines");
  write_text(dir / "cov.txt", "0 0 0 0 0 0 0 1 0.01 0 0 0 0.01 0 0 0 0.001\n");
  testing::expect_input_error(dir / "cov.txt", [&] { drain(options); }, "too few lines");
  // A line without a covariance; a covariance in both files.
  write_text(dir / "cov.txt", "0 0 0 0 0 0 0 1\n0 1 0 0 0 0 0 1 0.01 0 0 0 0.01 0 0 0 0.001\n");
  testing::expect_input_error(dir / "cov.txt", [&] { drain(options); }, "no covariance");
  options.poses = dir / "poses.txt";
  testing::expect_input_error(dir / "poses.txt", [&] { drain(options); }, "given twice");
}

TEST(SimulatedDrift, EstimatedScansAreTheTrueOnesDisplacedByTheError) {
  testing::TempDir dir("drift");
  sim::SimulationSpec spec = sim::make_preset("structured");
  spec.sensor = sim::sensor_preset("planar");
  spec.trajectory.scans = 4;
  spec.truth_resolution_m = 0;
  sim::SimulateOptions options;
  options.drift = {0.05, 0.01, 0, 0};
  {
    options.output_dir = dir / "drift";
    sim::simulate(spec, options);
  }
  sim::SimulateOptions still;
  still.output_dir = dir / "true";
  sim::simulate(spec, still);

  const std::vector<PoseRecord> estimated = read_pose_list(dir / "drift" / "poses.txt");
  const std::vector<PoseRecord> truth = read_pose_list(dir / "drift" / "poses_true.txt");
  ASSERT_EQ(estimated.size(), 4u);
  ASSERT_EQ(truth.size(), 4u);
  const std::vector<Scan> drifted = testing::read_all_scans({dir / "drift" / "scans"});
  const std::vector<Scan> exact = testing::read_all_scans({dir / "true" / "scans"});
  ASSERT_EQ(drifted.size(), 4u);
  for (size_t i = 0; i < 4; ++i) {
    // The covariance of scan i's error is (i + 1) Q.
    ASSERT_TRUE(estimated[i].covariance);
    EXPECT_NEAR((*estimated[i].covariance)(0, 0), (i + 1) * 0.05 * 0.05, 1e-15);
    EXPECT_NEAR((*estimated[i].covariance)(5, 5), (i + 1) * 0.01 * 0.01, 1e-15);
    EXPECT_EQ((*estimated[i].covariance)(2, 2), 0.0);
    EXPECT_FALSE(truth[i].covariance);
    EXPECT_EQ(drifted[i].pose.position.x, estimated[i].pose.position.x);
    EXPECT_EQ(exact[i].pose.position.x, truth[i].pose.position.x);
    // The error that maps the estimated scan onto the true one: t = true origin - estimated
    // origin, r = the yaw between the orientations (level poses: rotations about z).
    const Pose& e = drifted[i].pose;
    const Pose& t = exact[i].pose;
    const double yaw_e = 2 * std::atan2(double(e.qz), double(e.qw)), yaw_t = 2 * std::atan2(double(t.qz), double(t.qw));
    PoseSigmaPoint error;
    error.weight = 1;
    error.translation = {double(t.position.x) - e.position.x, double(t.position.y) - e.position.y, 0};
    error.rotation = {0, 0, yaw_t - yaw_e};
    EXPECT_GT(std::abs(error.translation.x) + std::abs(error.translation.y), 1e-4) << "scan " << i << " did not drift";
    ScanObservations est;
    est.origin = e.position;
    est.hits = drifted[i].points;
    ScanObservations moved;
    displace_observations(est, error, false, moved);
    ASSERT_EQ(moved.hits.size(), exact[i].points.size());
    for (size_t k = 0; k < moved.hits.size(); ++k) {
      const Vec3f& a = moved.hits[k];
      const Vec3f& b = exact[i].points[k];
      if (std::isnan(b.x)) {
        EXPECT_TRUE(std::isnan(a.x));
        continue;
      }
      EXPECT_NEAR(a.x, b.x, 2e-4);
      EXPECT_NEAR(a.y, b.y, 2e-4);
      EXPECT_NEAR(a.z, b.z, 2e-4);
    }
  }
}

// A sigma point may carry observations beyond the key range (a standard deviation up to the range
// itself is taken, and a scan may lie near its edge): those are dropped, as preprocessing drops
// points there, and the rest moved exactly; without its origin a scan keeps nothing. Nothing
// reaches the float rounding or the keys out of range.
TEST(DisplaceObservations, DropsWhatLeavesTheKeyRange) {
  ScanObservations in;
  in.origin = {999990, 0, 0};
  in.hits = {{999995, 0, 0}, {999985, 0, 0}, {999990, 5, 0}};
  in.free_ends = {{999994, 0, 0}, {999990, -5, 0}};
  in.kernel_weight = 0.5f;
  PoseSigmaPoint point;
  point.weight = 0.25;
  point.translation = {8, 0, 0};
  ScanObservations out;
  displace_observations(in, point, false, out);
  EXPECT_EQ(out.origin.x, 999998.0f);
  ASSERT_EQ(out.hits.size(), 2u);  // 1,000,003 m is beyond 1e6
  EXPECT_EQ(out.hits[0].x, 999993.0f);
  EXPECT_EQ(out.hits[1].x, 999998.0f);
  EXPECT_EQ(out.hits[1].y, 5.0f);
  ASSERT_EQ(out.free_ends.size(), 1u);
  EXPECT_EQ(out.free_ends[0].y, -5.0f);
  EXPECT_EQ(out.kernel_weight, 0.125f);
  // Half a turn about z through the origin: x mirrored about it, nothing beyond.
  point.translation = {};
  point.rotation = {0, 0, 3.141592653589793};
  displace_observations(in, point, false, out);
  ASSERT_EQ(out.hits.size(), 3u);
  EXPECT_NEAR(out.hits[0].x, 999985.0f, 0.07);
  EXPECT_NEAR(out.hits[1].x, 999995.0f, 0.07);
  EXPECT_NEAR(out.hits[2].y, -5.0f, 1e-6);
  for (const double far : {20.0, std::sqrt(6.0) * kMaxPoseTranslationSigmaM, -2.1e6}) {
    point = {};
    point.weight = 1;
    point.translation = {far, 0, 0};
    displace_observations(in, point, true, out);
    EXPECT_TRUE(out.hits.empty()) << far;
    EXPECT_TRUE(out.free_ends.empty()) << far;
  }
}

}  // namespace
}  // namespace bgkmap
