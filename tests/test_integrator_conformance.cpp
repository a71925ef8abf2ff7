// The back-end conformance suite: every integrator in kBackEnds builds the maps the brute-force
// oracle gives (within 1e-5 relative; pose uncertainty 2e-5) and, bit for bit, the maps of the
// portable CPU path (forgetting on or off), with the same pairs within l; reading and writing the
// host's cells through HostCells views between scans changes nothing. A new back end is one more entry in kBackEnds.
#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/integrate/bucketing.hpp"
#include "bgkmap/integrate/cpu_integrator.hpp"
#include "bgkmap/integrate/opencl_integrator.hpp"
#include "bgkmap/mapper.hpp"
#include "integrate/brute_force.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

using testing::small_params;

struct BackEnd {
  std::string name;
  DeviceKind kind;  // where it must run: no silent fallback
  // The integrator, or null with `why` when it cannot run here (no OpenCL device).
  std::function<std::unique_ptr<Integrator>(std::string& why)> make;
};

void PrintTo(const BackEnd& back_end, std::ostream* os) { *os << back_end.name; }

BackEnd opencl(const std::string& name, OpenClOptions::RowsPerWorkItem rows) {
  return {name, DeviceKind::kOpenCl, [rows](std::string& why) -> std::unique_ptr<Integrator> {
            OpenClOptions options;
            options.rows_per_work_item = rows;
            try {
              return make_opencl_integrator(options, 2);
            } catch (const OpenClUnavailable& e) {
              why = e.what();
              return nullptr;
            }
          }};
}

std::vector<BackEnd> back_ends() {
  using Rows = OpenClOptions::RowsPerWorkItem;
  return {
      {"cpu_portable", DeviceKind::kCpu, [](std::string&) { return std::make_unique<CpuIntegrator>(2, false); }},
      {"cpu", DeviceKind::kCpu, [](std::string&) { return std::make_unique<CpuIntegrator>(2); }},
      opencl("opencl_one_row", Rows::kOneRow),
      opencl("opencl_two_rows", Rows::kTwoRows),
      opencl("opencl_whole_block", Rows::kWholeBlock),
  };
}

class Conformance : public ::testing::TestWithParam<BackEnd> {
 protected:
  void SetUp() override {
    std::string why;
    if (GetParam().make(why)) return;
    if (::bgkmap::testing::running_in_ci()) FAIL() << GetParam().name << " cannot run: " << why;
    GTEST_SKIP() << GetParam().name << " cannot run here: " << why;
  }
  std::unique_ptr<Integrator> fresh() const {
    std::string why;
    return GetParam().make(why);
  }
  // The map under test beside the portable CPU path's, every scan inserted in both.
  // `forget_half_life` > 0: with forgetting, whose decay both paths leave to the host.
  void expect_same_as_cpu(const BuildParams& params, const std::vector<Scan>& scans, double forget_half_life = 0) const {
    Mapper reference(params, std::make_unique<CpuIntegrator>(2, false));
    Mapper tested(params, fresh());
    reference.set_forget_half_life(forget_half_life);
    tested.set_forget_half_life(forget_half_life);
    for (const Scan& s : scans) {
      reference.insert(s);
      tested.insert(s);
    }
    testing::expect_same_cells(reference.lazy_map(), tested.lazy_map());
    testing::expect_same_cells(reference.map(), tested.map());
    EXPECT_EQ(reference.counts().integrate.pairs_within_support, tested.counts().integrate.pairs_within_support);
    EXPECT_EQ(tested.backend().kind, GetParam().kind) << tested.backend().note;
    EXPECT_GT(reference.map().block_count(), 0u);
  }
};

// Every cell of every block against the oracle; most cells must have evidence.
void expect_brute_force(const BgkMap& map, const std::vector<ScanObservations>& obs) {
  const Grid& grid = map.grid();
  size_t checked = 0, with_evidence = 0;
  for (uint32_t slot = 0; slot < map.block_count(); ++slot) {
    const BlockKey key = map.key_of_slot(slot);
    for (int local = 0; local < grid.cells_per_block(); ++local) {
      const Vec3d c = grid.cell_center_d(grid.cell_at(key, local));
      const BruteForcePosterior ref = brute_force_cell(c, obs, map.params());
      const Cell& cell = map.block_cells(slot)[local];
      ASSERT_NEAR(cell.alpha, ref.alpha, 1e-5 * ref.alpha) << "cell " << c.x << "," << c.y << "," << c.z;
      ASSERT_NEAR(cell.beta, ref.beta, 1e-5 * ref.beta) << "cell " << c.x << "," << c.y << "," << c.z;
      ++checked;
      with_evidence += ref.alpha > map.params().prior.alpha0 || ref.beta > map.params().prior.beta0;
    }
  }
  EXPECT_GT(with_evidence, checked / 10);
}

TEST_P(Conformance, EqualsTheBruteForce) {
  for (const uint32_t seed : {1u, 2u}) {
    BuildParams params = small_params(seed == 2 ? 2 : 3);  // 8^3 blocks and another size
    const std::vector<Scan> scans = testing::random_scans(seed, 3, 150, 1.5f);
    Mapper mapper(params, fresh());
    for (const Scan& s : scans) mapper.insert(s);
    expect_brute_force(mapper.map(), testing::observations_of(scans, params));
    EXPECT_GT(mapper.counts().integrate.pairs_within_support, 0u);
    EXPECT_LE(mapper.counts().integrate.pairs_within_support, mapper.counts().integrate.pairs_evaluated);
  }
}

TEST_P(Conformance, TheCpuPathsBitsAtEveryBlockDepth) {
  for (const int depth : {1, 2, 3, 4}) {
    SCOPED_TRACE("block depth " + std::to_string(depth));
    expect_same_as_cpu(small_params(depth), testing::random_scans(7 + depth, 4, 200, 2.0f));
  }
}

TEST_P(Conformance, TheCpuPathsBitsWithForgetting) {
  // Scans far apart in turn, so blocks fall behind and are decayed before their next scan.
  std::vector<Scan> scans = testing::random_scans(23, 6, 200, 2.0f);
  for (size_t i = 1; i < scans.size(); i += 2) {
    for (Vec3f& p : scans[i].points) p.x += 8.0f;
    scans[i].pose.position.x += 8.0;
  }
  expect_same_as_cpu(small_params(4), scans, 1.5);
}

TEST_P(Conformance, TheCpuPathsBitsWithTheBoxKernelAndInAPlane) {
  BuildParams box = small_params(3);
  box.kernel.type = KernelType::kBox;
  expect_same_as_cpu(box, testing::random_scans(17, 4, 200, 2.0f));
  SCOPED_TRACE("planar");
  BuildParams planar = small_params(3);
  planar.set_planar(0.0);
  expect_same_as_cpu(planar, testing::random_scans(19, 4, 200, 2.0f));
}

// The expected sub-map reads and writes the hypotheses' blocks on the host (HostCells views);
// the expected kernel stays on the back end.
TEST_P(Conformance, PoseUncertaintyTheCpuPathsBits) {
  for (const PoseFusion fusion : {PoseFusion::kExpectedSubmap, PoseFusion::kExpectedKernel}) {
    SCOPED_TRACE(to_string(fusion));
    BuildParams params = small_params(3);
    params.preprocess.pose_fusion = fusion;
    std::vector<Scan> scans = testing::random_scans(31, 5, 200, 2.0f);
    // Certain scans first and last: the plain update before, the sub-map's blocks taken after.
    scans[1].pose_covariance = PoseCovariance::from_sigma({0.05, 0.03, 0.02, 0.01});
    scans[2].pose_covariance = PoseCovariance::from_planar({0.01, 0.002, 0, 0.002, 0.004, 0.0005, 0, 0.0005, 0.001});
    scans[3].pose_covariance = PoseCovariance{};
    expect_same_as_cpu(params, scans);
  }
}

TEST_P(Conformance, PoseUncertaintyEqualsTheBruteForce) {
  BuildParams params = small_params(3);
  params.preprocess.pose_fusion = PoseFusion::kExpectedSubmap;
  std::vector<Scan> scans = testing::random_scans(5, 3, 60, 1.5f);
  std::vector<PoseCovariance> covariances = {
      PoseCovariance::from_sigma({0.05, 0.03, 0.02, 0.01}),
      PoseCovariance::from_planar({0.01, 0.002, 0, 0.002, 0.004, 0.0005, 0, 0.0005, 0.001}), PoseCovariance{}};
  for (size_t i = 0; i < scans.size(); ++i) scans[i].pose_covariance = covariances[i];
  Mapper mapper(params, fresh());
  for (const Scan& s : scans) mapper.insert(s);
  const BgkMap& map = mapper.map();
  std::vector<Vec3d> centers;
  std::vector<Cell> cells;
  for (uint32_t slot = 0; slot < map.block_count(); ++slot)
    for (int local = 0; local < map.cells_per_block(); ++local) {
      centers.push_back(map.grid().cell_center_d(map.grid().cell_at(map.key_of_slot(slot), local)));
      cells.push_back(map.block_cells(slot)[local]);
    }
  const std::vector<BruteForcePosterior> refs =
      brute_force_expected_submap_cells(centers, testing::observations_of(scans, params), covariances, params);
  const double abs_tol = 1e-9 * params.kernel.sigma0;  // sums of a few pairs near l, inputs rounded to float
  size_t with_evidence = 0;
  for (size_t i = 0; i < centers.size(); ++i) {
    ASSERT_NEAR(cells[i].alpha, refs[i].alpha, 2e-5 * refs[i].alpha + abs_tol) << i;
    ASSERT_NEAR(cells[i].beta, refs[i].beta, 2e-5 * refs[i].beta + abs_tol) << i;
    with_evidence += refs[i].alpha > params.prior.alpha0 || refs[i].beta > params.prior.beta0;
  }
  EXPECT_GT(with_evidence, centers.size() / 10);
}

// Buckets `obs` into `map` and integrates it, as the Mapper does.
void integrate_scan(Integrator& integrator, const ScanObservations& obs, BgkMap& map, IntegrateStats& stats) {
  ScanBuckets buckets;
  const BuildParams& params = map.params();
  bucket_scan(map.grid(), params.kernel.support_radius_m(params.grid.resolution_m), obs, buckets);
  for (BlockWork& w : buckets.blocks) w.slot = map.ensure_slot(w.key);
  integrator.integrate(obs, buckets, map, stats);
}

// Between scans: every cell read through a view, then the cells of some slots set to the prior
// through a read-write view of those slots; the next scans build on the host's cells. The
// portable CPU path, doing the same, gives the same bits; so does a second map on the same
// integrator (announced with an overwrite view).
TEST_P(Conformance, HostViewsBetweenScans) {
  const BuildParams params = small_params(3);
  const std::vector<ScanObservations> obs = testing::observations_of(testing::random_scans(41, 6, 200, 2.0f), params);
  const std::vector<uint32_t> forgotten = {0, 2};
  const auto build = [&](Integrator& integrator) {
    BgkMap map(params);
    IntegrateStats stats;
    integrator.host_cells(map, stats, HostAccess::kOverwrite);  // a new map for this integrator
    for (size_t i = 0; i < obs.size(); ++i) {
      integrate_scan(integrator, obs[i], map, stats);
      if (i == 1) integrator.host_cells(map, stats, HostAccess::kRead);
      if (i != 3) continue;
      const HostCells cells = integrator.host_cells(map, forgotten, stats, HostAccess::kReadWrite);
      const Cell prior{params.prior.alpha0, params.prior.beta0};
      for (const uint32_t slot : forgotten) {
        Cell* c = cells.map().block_cells(slot);
        const size_t n = static_cast<size_t>(map.cells_per_block());
        // The view holds the scans so far: some cell of the slot has evidence to forget.
        EXPECT_TRUE(std::any_of(c, c + n, [&](const Cell& x) { return x.alpha != prior.alpha || x.beta != prior.beta; }));
        std::fill(c, c + n, prior);
      }
    }
    integrator.host_cells(map, stats, HostAccess::kRead);
    return map;
  };
  CpuIntegrator cpu(2, false);
  const BgkMap reference = build(cpu);
  const std::unique_ptr<Integrator> tested = fresh();
  const BgkMap first = build(*tested);
  testing::expect_same_cells(reference, first);
  const BgkMap second = build(*tested);
  testing::expect_same_cells(reference, second);
  EXPECT_EQ(tested->info().kind, GetParam().kind) << tested->info().note;
}

INSTANTIATE_TEST_SUITE_P(BackEnds, Conformance, ::testing::ValuesIn(back_ends()),
                         [](const ::testing::TestParamInfo<BackEnd>& p) { return p.param.name; });

}  // namespace
}  // namespace bgkmap
