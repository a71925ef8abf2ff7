// The CPU back end against plain references: brute force (sparse kernel), the counting sensor
// model (box kernel), order independence and station keeping.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>

#include "core/bgk_math.h"
#include "integrate/brute_force.hpp"
#include "bgkmap/integrate/bucketing.hpp"
#include "bgkmap/integrate/cpu_integrator.hpp"
#include "bgkmap/mapper.hpp"
#include "integrate/beam_rows_8.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

using testing::small_params;

// Every cell of every block in the map equals the brute-force posterior within 1e-5 relative.
void expect_map_matches_brute_force(const BgkMap& map, const std::vector<ScanObservations>& obs, double rel_tol) {
  const Grid& grid = map.grid();
  size_t checked = 0, with_evidence = 0;
  for (uint32_t slot = 0; slot < map.block_count(); ++slot) {
    const BlockKey key = map.key_of_slot(slot);
    const Cell* cells = map.block_cells(slot);
    for (int local = 0; local < grid.cells_per_block(); ++local) {
      const Vec3d c = grid.cell_center_d(grid.cell_at(key, local));
      const BruteForcePosterior ref = brute_force_cell(c, obs, map.params());
      ASSERT_NEAR(cells[local].alpha, ref.alpha, rel_tol * ref.alpha) << "cell " << c.x << "," << c.y << "," << c.z;
      ASSERT_NEAR(cells[local].beta, ref.beta, rel_tol * ref.beta) << "cell " << c.x << "," << c.y << "," << c.z;
      ++checked;
      with_evidence += ref.alpha > map.params().prior.alpha0 || ref.beta > map.params().prior.beta0;
    }
  }
  EXPECT_GT(with_evidence, checked / 10);
}

TEST(CpuIntegrator, EqualsBruteForceOnRandomScenes) {
  for (uint32_t seed : {1u, 2u, 3u}) {
    BuildParams params = small_params();
    params.grid.block_depth = seed == 3 ? 4 : 3;  // 4^3 blocks (the any-size path) and 8^3 ones
    const auto scans = testing::random_scans(seed, 3, 150, 1.5f);
    Mapper mapper(params, std::make_unique<CpuIntegrator>(2));
    for (const Scan& s : scans) mapper.insert(s);
    expect_map_matches_brute_force(mapper.map(), testing::observations_of(scans, params), 1e-5);
    EXPECT_GT(mapper.counts().integrate.pairs_within_support, 0u);
    EXPECT_LE(mapper.counts().integrate.pairs_within_support, mapper.counts().integrate.pairs_evaluated);
  }
}

// The 8^3 paths evaluate only the cells their culling keeps (beams: the rows' intervals). Pairs
// within l, as the back end counts them, must equal those of every (cell, observation) pair of
// every touched block with the same float expressions: one skipped pair within l would make the
// count smaller (a map comparison would not see a pair near l, whose weight is ~1e-10 sigma0).
// Beams along and nearly along each axis and diagonals test the culling's special cases.
TEST(CpuIntegrator, CullingNeverSkipsAPairWithinL) {
  for (double ell : {0.2, 0.35, 0.05}) {
    BuildParams params = small_params();
    params.grid.block_depth = 4;  // 8^3 blocks
    params.kernel.ell_m = static_cast<float>(ell);
    std::vector<Scan> scans = testing::random_scans(41, 2, 300, 1.5f);
    Scan axes;
    axes.pose.position = {0.013f, -0.021f, 0.007f};
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> tiny(-1e-3f, 1e-3f), len(0.3f, 2.4f);
    for (int axis = 0; axis < 3; ++axis)
      for (float sign : {-1.0f, 1.0f})
        for (int k = 0; k < 12; ++k) {
          Vec3f d{0, 0, 0};
          if (k % 3 != 0) d = {tiny(rng) * (k % 3), tiny(rng) * (k % 3), tiny(rng) * (k % 3)};  // exact, then nearly
          (axis == 0 ? d.x : axis == 1 ? d.y : d.z) = sign;
          const float n = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z), r = len(rng);
          const Vec3f offset{0.05f * (k % 4), -0.04f * (k % 5), 0.03f * (k % 3)};
          axes.points.push_back({axes.pose.position.x + offset.x + d.x / n * r,
                                 axes.pose.position.y + offset.y + d.y / n * r,
                                 axes.pose.position.z + offset.z + d.z / n * r});
        }
    for (int k = 0; k < 40; ++k) {  // diagonals
      const float a = 0.157f * k, e = 0.3f * std::sin(0.7f * k), r = len(rng);
      axes.points.push_back({axes.pose.position.x + r * std::cos(a) * std::cos(e),
                             axes.pose.position.y + r * std::sin(a) * std::cos(e), axes.pose.position.z + r * std::sin(e)});
    }
    scans.push_back(axes);

    BgkMap map(params);
    CpuIntegrator cpu(2);
    const float res = static_cast<float>(params.grid.resolution_m);
    const float ell2 = params.kernel.ell_m * params.kernel.ell_m;
    uint64_t expected = 0, every_pair = 0;
    IntegrateStats stats;
    for (const ScanObservations& obs : testing::observations_of(scans, params)) {
      ScanBuckets buckets;
      bucket_scan(map.grid(), params.kernel.support_radius_m(params.grid.resolution_m), obs, buckets);
      for (BlockWork& w : buckets.blocks) w.slot = map.ensure_slot(w.key);
      cpu.integrate(obs, buckets, map, stats);
      ASSERT_EQ(map.grid().cells_per_side(), 8);
      for (const BlockWork& w : buckets.blocks) {
        every_pair += 512u * (w.hit_count + w.beam_count);
        for (int z = 0; z < 8; ++z)
          for (int y = 0; y < 8; ++y)
            for (int x = 0; x < 8; ++x) {
              for (uint32_t i = 0; i < w.hit_count; ++i) {
                const LocalHit& h = buckets.hits[w.hit_begin + i];
                const float dx = x * res - h.x, dy = y * res - h.y, dz = z * res - h.z;
                expected += dx * dx + (dy * dy + dz * dz) < ell2;
              }
              for (uint32_t i = 0; i < w.beam_count; ++i) {
                const LocalBeam& b = buckets.beams[w.beam_begin + i];
                expected += bgk_anchored_segment_dist2(x * res, y * res, z * res, b.qx, b.qy, b.qz, b.ux, b.uy, b.uz,
                                                       b.s_min, b.s_max) < ell2;
              }
            }
      }
    }
    cpu.finish(stats);
    EXPECT_GT(expected, 5000u) << "ell " << ell;
    EXPECT_EQ(stats.pairs_within_support, expected) << "ell " << ell;
    // The culling does cull: whole rows are evaluated, two at a time, but only those a hit or beam
    // can reach (here 9-35 % of the touched blocks' pairs).
    EXPECT_LT(stats.pairs_evaluated, every_pair / 2) << "ell " << ell;
  }
}

// A planar map (--2d): preprocessing moves every point and origin onto the layer's centre plane,
// the layer's cells equal the brute force of those planar observations (distances in the plane),
// and every other cell stays at the prior. Depth 3 (the any-size path), 4 (8^3 rows, hits and
// beams masked to the layer) and 5, the box kernel too.
TEST(CpuIntegrator, PlanarMapIsTheLayerOfTheBruteForceInThePlane) {
  struct Case {
    int depth;
    KernelType kernel;
    double plane_z;
  };
  for (const Case& c : {Case{3, KernelType::kSparse, 0.0}, Case{4, KernelType::kSparse, -0.23},
                        Case{4, KernelType::kBox, 0.0}, Case{5, KernelType::kSparse, 0.31}}) {
    SCOPED_TRACE("depth " + std::to_string(c.depth) + ", plane " + std::to_string(c.plane_z));
    BuildParams params = small_params();
    params.grid.block_depth = c.depth;
    params.kernel.type = c.kernel;
    params.set_planar(c.plane_z);
    const double plane = params.preprocess.plane_z_m;
    EXPECT_NEAR(plane, (params.planar_layer() + 0.5) * params.grid.resolution_m, 1e-12);
    const auto scans = testing::random_scans(11, 3, 150, 1.5f);  // 3-D points, moved onto the plane
    Mapper mapper(params, std::make_unique<CpuIntegrator>(2));
    for (const Scan& s : scans) mapper.insert(s);
    const auto obs = testing::observations_of(scans, params);
    for (const ScanObservations& o : obs) {
      EXPECT_EQ(o.origin.z, static_cast<float>(plane));
      for (const Vec3f& h : o.hits) ASSERT_EQ(h.z, static_cast<float>(plane));
      for (const Vec3f& e : o.free_ends) ASSERT_EQ(e.z, static_cast<float>(plane));
    }
    const BgkMap& map = mapper.map();
    const Grid& grid = map.grid();
    size_t layer_cells = 0, with_evidence = 0;
    for (uint32_t slot = 0; slot < map.block_count(); ++slot) {
      const BlockKey key = map.key_of_slot(slot);
      const Cell* cells = map.block_cells(slot);
      for (int local = 0; local < grid.cells_per_block(); ++local) {
        const CellIndex cell = grid.cell_at(key, local);
        if (cell.z != params.planar_layer()) {
          ASSERT_EQ(cells[local].alpha, params.prior.alpha0);
          ASSERT_EQ(cells[local].beta, params.prior.beta0);
          continue;
        }
        const BruteForcePosterior ref = brute_force_cell(grid.cell_center_d(cell), obs, params);
        ASSERT_NEAR(cells[local].alpha, ref.alpha, 1e-5 * ref.alpha) << local;
        ASSERT_NEAR(cells[local].beta, ref.beta, 1e-5 * ref.beta) << local;
        ++layer_cells;
        with_evidence += ref.alpha > params.prior.alpha0 || ref.beta > params.prior.beta0;
      }
    }
    EXPECT_GT(with_evidence, 200u);
    EXPECT_GT(with_evidence, layer_cells / 10);
    // A planar map answers for its layer whatever the height asked.
    const CellPosterior at_plane = map.query(0.31, -0.27, plane), above = map.query(0.31, -0.27, plane + 7.3);
    EXPECT_EQ(at_plane.alpha, above.alpha);
    EXPECT_EQ(at_plane.beta, above.beta);
  }
}

TEST(CpuIntegrator, CellsOutsideTheTouchedBlocksHaveNoEvidence) {
  // Brute force over a region larger than the map: cells of untouched blocks must be at the prior.
  const BuildParams params = small_params();
  const auto scans = testing::random_scans(9, 1, 40, 1.0f);
  Mapper mapper(params, std::make_unique<CpuIntegrator>(1));
  mapper.insert(scans[0]);
  const auto obs = testing::observations_of(scans, params);
  const BgkMap& map = mapper.map();
  const Grid& grid = map.grid();
  for (int32_t z = -15; z < 15; ++z)
    for (int32_t y = -15; y < 15; ++y)
      for (int32_t x = -15; x < 15; ++x) {
        const CellIndex cell{x, y, z};
        if (map.find_slot(grid.block_of(cell)) >= 0) continue;
        const BruteForcePosterior ref = brute_force_cell(grid.cell_center_d(cell), obs, params);
        ASSERT_EQ(ref.alpha, params.prior.alpha0);
        ASSERT_EQ(ref.beta, params.prior.beta0);
      }
}

// Counting sensor model (the paper's Algorithm 1) by 3-D DDA over cells: every cell the free
// segment traverses counts a miss, the cell holding the hit counts a hit.
std::map<std::tuple<int, int, int>, std::pair<int, int>> counting_model(const std::vector<ScanObservations>& scans,
                                                                        const Grid& grid) {
  std::map<std::tuple<int, int, int>, std::pair<int, int>> counts;
  const double res = grid.resolution();
  for (const ScanObservations& s : scans) {
    for (const Vec3f& h : s.hits) {
      const CellIndex c = grid.cell_of(h.x, h.y, h.z);
      ++counts[{c.x, c.y, c.z}].first;
    }
    for (const Vec3f& e : s.free_ends) {
      const double o[3] = {s.origin.x, s.origin.y, s.origin.z};
      const double v[3] = {double(e.x) - s.origin.x, double(e.y) - s.origin.y, double(e.z) - s.origin.z};
      CellIndex c = grid.cell_of(o[0], o[1], o[2]);
      const CellIndex last = grid.cell_of(e.x, e.y, e.z);
      int* axis[3] = {&c.x, &c.y, &c.z};
      double t_max[3], t_delta[3];
      int step[3];
      for (int a = 0; a < 3; ++a) {
        step[a] = v[a] > 0 ? 1 : (v[a] < 0 ? -1 : 0);
        t_delta[a] = step[a] ? std::abs(res / v[a]) : INFINITY;
        t_max[a] = step[a] ? ((*axis[a] + (step[a] > 0 ? 1 : 0)) * res - o[a]) / v[a] : INFINITY;
      }
      ++counts[{c.x, c.y, c.z}].second;
      while (!(c == last)) {
        const int a = t_max[0] < t_max[1] ? (t_max[0] < t_max[2] ? 0 : 2) : (t_max[1] < t_max[2] ? 1 : 2);
        if (t_max[a] > 1.0) break;
        *axis[a] += step[a];
        t_max[a] += t_delta[a];
        ++counts[{c.x, c.y, c.z}].second;
      }
    }
  }
  return counts;
}

TEST(CpuIntegrator, BoxKernelIsTheCountingSensorModel) {
  BuildParams params = small_params();
  params.kernel.type = KernelType::kBox;
  const auto scans = testing::random_scans(5, 3, 120, 1.5f);
  Mapper mapper(params, std::make_unique<CpuIntegrator>(2));
  for (const Scan& s : scans) mapper.insert(s);
  const auto expected = counting_model(testing::observations_of(scans, params), mapper.map().grid());
  const BgkMap& map = mapper.map();
  const Grid& grid = map.grid();
  size_t cells_with_counts = 0;
  for (uint32_t slot = 0; slot < map.block_count(); ++slot) {
    for (int local = 0; local < grid.cells_per_block(); ++local) {
      const CellIndex c = grid.cell_at(map.key_of_slot(slot), local);
      const auto it = expected.find({c.x, c.y, c.z});
      const int hits = it == expected.end() ? 0 : it->second.first;
      const int misses = it == expected.end() ? 0 : it->second.second;
      const Cell& cell = map.block_cells(slot)[local];
      // Counts are integers; float sums over scans only round the prior's share.
      ASSERT_NEAR(cell.alpha - params.prior.alpha0, hits, 1e-4) << c.x << "," << c.y << "," << c.z;
      ASSERT_NEAR(cell.beta - params.prior.beta0, misses, 1e-4) << c.x << "," << c.y << "," << c.z;
      cells_with_counts += (hits + misses) > 0;
    }
  }
  // And no counted cell lies outside the map's blocks.
  for (const auto& [key, hm] : expected) {
    const CellIndex c{std::get<0>(key), std::get<1>(key), std::get<2>(key)};
    EXPECT_GE(map.find_slot(grid.block_of(c)), 0);
  }
  EXPECT_EQ(cells_with_counts, expected.size());
}

TEST(CpuIntegrator, ScanOrderDoesNotMatter) {
  const BuildParams params = small_params();
  auto scans = testing::random_scans(21, 4, 200, 1.5f);
  Mapper forward(params, std::make_unique<CpuIntegrator>(2));
  for (const Scan& s : scans) forward.insert(s);
  Mapper backward(params, std::make_unique<CpuIntegrator>(1));
  for (auto it = scans.rbegin(); it != scans.rend(); ++it) backward.insert(*it);
  const BgkMap& a = forward.map();
  const BgkMap& b = backward.map();
  ASSERT_EQ(a.block_count(), b.block_count());
  for (uint32_t slot = 0; slot < a.block_count(); ++slot) {
    const int64_t other = b.find_slot(a.key_of_slot(slot));
    ASSERT_GE(other, 0);
    for (int i = 0; i < a.cells_per_block(); ++i) {
      const Cell& x = a.block_cells(slot)[i];
      const Cell& y = b.block_cells(uint32_t(other))[i];
      ASSERT_NEAR(x.alpha, y.alpha, 1e-5 * x.alpha);
      ASSERT_NEAR(x.beta, y.beta, 1e-5 * x.beta);
    }
  }
}

TEST(CpuIntegrator, ThreadCountDoesNotChangeTheMap) {
  const BuildParams params = small_params();
  const auto scans = testing::random_scans(33, 2, 300, 1.5f);
  Mapper one(params, std::make_unique<CpuIntegrator>(1));
  Mapper two(params, std::make_unique<CpuIntegrator>(2));
  for (const Scan& s : scans) {
    one.insert(s);
    two.insert(s);
  }
  // Blocks are independent and each cell sums in bucket order: bit-identical.
  EXPECT_EQ(one.map().cell_pool().size(), two.map().cell_pool().size());
  for (size_t i = 0; i < one.map().cell_pool().size(); ++i) {
    ASSERT_EQ(one.map().cell_pool()[i].alpha, two.map().cell_pool()[i].alpha);
    ASSERT_EQ(one.map().cell_pool()[i].beta, two.map().cell_pool()[i].beta);
  }
}

#if BGK_AVX512_BEAMS
// Where the CPU has AVX-512, the beams of 8^3 blocks run in intrinsics (items of up to 64 beams,
// software pipelined) instead of the portable row-pair loop: the same float operations on the
// same inputs, added to each cell in the same order, so the same sums bit for bit and the same
// pair counts. Blocks near the origin get more beams than one batch holds.
TEST(CpuIntegrator, Avx512BeamsAreThePortableSums) {
  if (!cpu_runs_avx512_beams()) GTEST_SKIP() << "this CPU has no AVX-512 (x86-64-v4)";
  BuildParams params = small_params();
  params.grid.block_depth = 4;
  const auto scans = testing::random_scans(44, 3, 400, 1.5f);
  ScanBuckets buckets;
  bucket_scan(Grid(params.grid), params.kernel.support_radius_m(params.grid.resolution_m),
              testing::observations_of(scans, params)[0], buckets);
  uint32_t most_beams = 0;
  for (const BlockWork& work : buckets.blocks) most_beams = std::max(most_beams, work.beam_count);
  ASSERT_GT(most_beams, 2 * 64u);

  Mapper widest(params, std::make_unique<CpuIntegrator>(2));
  Mapper portable(params, std::make_unique<CpuIntegrator>(2, /*avx512_beams=*/false));
  for (const Scan& s : scans) {
    widest.insert(s);
    portable.insert(s);
  }
  ASSERT_EQ(widest.map().cell_pool().size(), portable.map().cell_pool().size());
  size_t with_evidence = 0;
  for (size_t i = 0; i < widest.map().cell_pool().size(); ++i) {
    ASSERT_EQ(widest.map().cell_pool()[i].alpha, portable.map().cell_pool()[i].alpha) << "cell " << i;
    ASSERT_EQ(widest.map().cell_pool()[i].beta, portable.map().cell_pool()[i].beta) << "cell " << i;
    with_evidence += widest.map().cell_pool()[i].beta > params.prior.beta0;
  }
  EXPECT_GT(with_evidence, widest.map().cell_pool().size() / 4);
  EXPECT_EQ(widest.counts().integrate.pairs_evaluated, portable.counts().integrate.pairs_evaluated);
  EXPECT_EQ(widest.counts().integrate.pairs_within_support, portable.counts().integrate.pairs_within_support);
}
#endif

TEST(CpuIntegrator, StationKeeping) {
  // One scan inserted 60 times: the mean holds where evidence dwarfs the prior, the variance
  // shrinks with every insertion.
  const BuildParams params = small_params();
  const auto scans = testing::random_scans(4, 1, 300, 1.5f);
  Mapper mapper(params, std::make_unique<CpuIntegrator>(2));
  mapper.insert(scans[0]);
  const CellPool once = mapper.map().cell_pool();
  CellPool previous = once;
  for (int k = 2; k <= 60; ++k) {
    mapper.insert(scans[0]);
    const CellPool& now = mapper.map().cell_pool();
    ASSERT_EQ(now.size(), once.size());
    for (size_t i = 0; i < now.size(); ++i) {
      const CellPosterior p1 = mapper.map().posterior(previous[i]);
      const CellPosterior pk = mapper.map().posterior(now[i]);
      // Float alpha/beta can only grow by more than an ulp where the scan brings real evidence.
      const double evidence = (once[i].alpha - params.prior.alpha0) + (once[i].beta - params.prior.beta0);
      if (evidence < 1e-4) continue;
      ASSERT_LT(pk.variance(), p1.variance()) << "cell " << i << " insertion " << k;
    }
    previous = now;
  }
  size_t compared = 0;
  for (size_t i = 0; i < once.size(); ++i) {
    const double evidence = (once[i].alpha - params.prior.alpha0) + (once[i].beta - params.prior.beta0);
    // Where evidence is 1000x the prior, the prior moves the mean by less than ~1e-3.
    if (evidence < 1000 * (params.prior.alpha0 + params.prior.beta0)) continue;
    const CellPosterior p1 = mapper.map().posterior(once[i]);
    const CellPosterior p60 = mapper.map().posterior(previous[i]);
    EXPECT_NEAR(p60.mean(), p1.mean(), 1e-3);
    ++compared;
  }
  EXPECT_GT(compared, 10u);
}

}  // namespace
}  // namespace bgkmap
