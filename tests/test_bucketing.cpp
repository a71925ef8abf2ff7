// Bucketing is exact: every observation within the support radius of a cell centre reaches
// that cell's block, and every bucketed block really lies within reach.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <ostream>
#include <random>
#include <set>

#include "core/bgk_math.h"
#include "bgkmap/integrate/bucketing.hpp"
#include "integrate/box_distance.hpp"

namespace bgkmap {
namespace {

ScanObservations random_observations(std::mt19937& rng, int hits, int beams, float extent) {
  std::uniform_real_distribution<float> u(-extent, extent);
  ScanObservations obs;
  obs.origin = {u(rng) * 0.3f, u(rng) * 0.3f, u(rng) * 0.3f};
  for (int i = 0; i < hits; ++i) obs.hits.push_back({u(rng), u(rng), u(rng)});
  for (int i = 0; i < beams; ++i) obs.free_ends.push_back({u(rng), u(rng), u(rng)});
  return obs;
}

std::set<std::pair<BlockKey, uint32_t>> bucketed_pairs(const ScanBuckets& b, bool hits) {
  std::set<std::pair<BlockKey, uint32_t>> out;
  for (const BlockWork& w : b.blocks) {
    const uint32_t begin = hits ? w.hit_begin : w.beam_begin, count = hits ? w.hit_count : w.beam_count;
    for (uint32_t i = 0; i < count; ++i) out.insert({w.key, (hits ? b.hit_ids : b.beam_ids)[begin + i]});
  }
  return out;
}

struct BucketCase {
  double resolution;
  int depth;
  float radius;
};
// gtest names the failing case by it (else a dump of its bytes).
void PrintTo(const BucketCase& c, std::ostream* out) {
  *out << "resolution " << c.resolution << " m, depth " << c.depth << ", radius " << c.radius << " m";
}

class BucketingBruteForce : public ::testing::TestWithParam<BucketCase> {};

TEST_P(BucketingBruteForce, NoCellWithinReachIsMissed) {
  const BucketCase c = GetParam();
  GridParams gp;
  gp.resolution_m = c.resolution;
  gp.block_depth = c.depth;
  const Grid grid(gp);
  std::mt19937 rng(11 + c.depth);
  const float extent = 1.5f;
  const ScanObservations obs = random_observations(rng, 40, 40, extent);
  ScanBuckets buckets;
  bucket_scan(grid, c.radius, obs, buckets);
  const auto hit_pairs = bucketed_pairs(buckets, true);
  const auto beam_pairs = bucketed_pairs(buckets, false);

  // Brute force over every cell centre of the region.
  const float r2 = c.radius * c.radius;
  const CellIndex lo = grid.cell_of(-extent - c.radius - 0.2, -extent - c.radius - 0.2, -extent - c.radius - 0.2);
  const CellIndex hi = grid.cell_of(extent + c.radius + 0.2, extent + c.radius + 0.2, extent + c.radius + 0.2);
  size_t needed_hits = 0, needed_beams = 0;
  std::set<std::pair<BlockKey, uint32_t>> needed_hit_pairs, needed_beam_pairs;
  for (int32_t z = lo.z; z <= hi.z; ++z)
    for (int32_t y = lo.y; y <= hi.y; ++y)
      for (int32_t x = lo.x; x <= hi.x; ++x) {
        const CellIndex cell{x, y, z};
        const Vec3f ctr = grid.cell_center(cell);
        const BlockKey key = grid.block_of(cell);
        for (uint32_t i = 0; i < obs.hits.size(); ++i) {
          const Vec3f& p = obs.hits[i];
          const float d2 = (ctr.x - p.x) * (ctr.x - p.x) + (ctr.y - p.y) * (ctr.y - p.y) + (ctr.z - p.z) * (ctr.z - p.z);
          if (d2 < r2) needed_hit_pairs.insert({key, i});
        }
        for (uint32_t i = 0; i < obs.free_ends.size(); ++i) {
          const Vec3f& e = obs.free_ends[i];
          const float d2 = bgk_point_segment_dist2(ctr.x, ctr.y, ctr.z, obs.origin.x, obs.origin.y, obs.origin.z, e.x, e.y, e.z);
          if (d2 < r2) needed_beam_pairs.insert({key, i});
        }
      }
  for (const auto& p : needed_hit_pairs) {
    ++needed_hits;
    EXPECT_TRUE(hit_pairs.count(p)) << "hit " << p.second << " missed block " << p.first.x << "," << p.first.y << "," << p.first.z;
  }
  for (const auto& p : needed_beam_pairs) {
    ++needed_beams;
    EXPECT_TRUE(beam_pairs.count(p)) << "beam " << p.second << " missed block " << p.first.x << "," << p.first.y << "," << p.first.z;
  }
  EXPECT_GT(needed_hits, 0u);
  EXPECT_GT(needed_beams, 0u);
  // Block-level conservatism only: the bucketed pairs are few more than the needed ones.
  EXPECT_LE(hit_pairs.size(), 4 * needed_hit_pairs.size() + 8);
  EXPECT_LE(beam_pairs.size(), 4 * needed_beam_pairs.size() + 8);
}

INSTANTIATE_TEST_SUITE_P(Geometries, BucketingBruteForce,
                         ::testing::Values(BucketCase{0.1, 4, 0.2f}, BucketCase{0.1, 2, 0.2f},
                                           BucketCase{0.1, 1, 0.35f}, BucketCase{0.2, 3, 0.6f},
                                           BucketCase{0.05, 4, 0.03f}, BucketCase{0.1, 4, 1.3f}));

TEST(Bucketing, EveryBucketedBlockIsWithinReachBySampling) {
  GridParams gp;
  const Grid grid(gp);
  std::mt19937 rng(3);
  const ScanObservations obs = random_observations(rng, 20, 30, 2.0f);
  ScanBuckets buckets;
  const float r = 0.2f;
  bucket_scan(grid, r, obs, buckets);
  for (const BlockWork& w : buckets.blocks) {
    const Aabb box = grid.block_center_box(w.key);
    for (uint32_t i = 0; i < w.beam_count; ++i) {
      const Vec3f& e = obs.free_ends[buckets.beam_ids[w.beam_begin + i]];
      double best = 1e30;
      for (int s = 0; s <= 4000; ++s) {
        const double t = s / 4000.0;
        const Vec3f q{float(obs.origin.x + t * (e.x - obs.origin.x)), float(obs.origin.y + t * (e.y - obs.origin.y)),
                      float(obs.origin.z + t * (e.z - obs.origin.z))};
        best = std::min(best, point_box_dist2(q, box));
      }
      EXPECT_LT(std::sqrt(best), r + 0.01) << "beam bucketed into a block out of reach";
    }
  }
}

TEST(Bucketing, ThreadCountDoesNotChangeTheBuckets) {
  GridParams gp;
  const Grid grid(gp);
  std::mt19937 rng(5);
  const ScanObservations obs = random_observations(rng, 3000, 3000, 3.0f);
  ScanBuckets one;
  bucket_scan(grid, 0.2f, obs, one, 1);
  for (const int threads : {2, 3, 7}) {  // 8, 12 and 28 parts
    ScanBuckets many;
    bucket_scan(grid, 0.2f, obs, many, threads);
    ASSERT_EQ(one.blocks.size(), many.blocks.size()) << threads << " threads";
    for (size_t b = 0; b < one.blocks.size(); ++b) {
      EXPECT_EQ(one.blocks[b].key, many.blocks[b].key);
      EXPECT_EQ(one.blocks[b].hit_begin, many.blocks[b].hit_begin);
      EXPECT_EQ(one.blocks[b].hit_count, many.blocks[b].hit_count);
      EXPECT_EQ(one.blocks[b].beam_begin, many.blocks[b].beam_begin);
      EXPECT_EQ(one.blocks[b].beam_count, many.blocks[b].beam_count);
    }
    EXPECT_EQ(one.beam_ids, many.beam_ids) << threads << " threads";
    EXPECT_EQ(one.hit_ids, many.hit_ids) << threads << " threads";
  }
}

// The first `blocks` blocks of a and b hold the same keys and the same observations in the same
// order (where the id arrays place each block's range may differ).
void expect_same_blocks(const ScanBuckets& a, const ScanBuckets& b, size_t blocks, const char* what) {
  SCOPED_TRACE(what);
  ASSERT_GE(a.blocks.size(), blocks);
  ASSERT_GE(b.blocks.size(), blocks);
  auto ids = [](const ScanBuckets& s, const BlockWork& w, bool hits) {
    const std::vector<uint32_t>& all = hits ? s.hit_ids : s.beam_ids;
    const uint32_t begin = hits ? w.hit_begin : w.beam_begin, count = hits ? w.hit_count : w.beam_count;
    return std::vector<uint32_t>(all.begin() + begin, all.begin() + begin + count);
  };
  for (size_t i = 0; i < blocks; ++i) {
    EXPECT_EQ(a.blocks[i].key, b.blocks[i].key);
    EXPECT_EQ(ids(a, a.blocks[i], true), ids(b, b.blocks[i], true)) << "block " << i;
    EXPECT_EQ(ids(a, a.blocks[i], false), ids(b, b.blocks[i], false)) << "block " << i;
  }
}

TEST(Bucketing, DenseAndHashedBlockNumbersGiveTheSameBuckets) {
  // Blocks are numbered through a dense array over the scan's extent when it is small enough,
  // else through a hash table; the buckets must not tell which.
  GridParams gp;
  const Grid grid(gp);
  std::mt19937 rng(6);
  const ScanObservations near = random_observations(rng, 2000, 2000, 3.0f);
  // One more hit kilometres away: an extent far beyond any dense array, so every key is hashed.
  ScanObservations far = near;
  far.hits.push_back({4000.0f, 3000.0f, 2000.0f});
  for (const int threads : {1, 3}) {
    ScanBuckets dense, hashed;
    bucket_scan(grid, 0.2f, near, dense, threads);
    bucket_scan(grid, 0.2f, far, hashed, threads);
    // The far hit's blocks sort last (largest x) and hold its id, the last: the rest is equal.
    ASSERT_GT(hashed.blocks.size(), dense.blocks.size());
    EXPECT_GT(hashed.blocks[dense.blocks.size()].key.x, 1000);
    expect_same_blocks(dense, hashed, dense.blocks.size(), threads == 1 ? "1 thread" : "3 threads");
    EXPECT_EQ(dense.beam_ids.size(), hashed.beam_ids.size());
    EXPECT_EQ(dense.hit_ids.size() + (hashed.blocks.size() - dense.blocks.size()), hashed.hit_ids.size());
  }
  // An extent of 60^3 blocks: dense for one thread's part; 28 parts on 7 threads would take more
  // than their share of dense entries and hash, while the global numbering stays dense.
  const ScanObservations wide = random_observations(rng, 500, 1500, 24.0f);
  ScanBuckets one, many;
  bucket_scan(grid, 0.2f, wide, one, 1);
  bucket_scan(grid, 0.2f, wide, many, 7);
  ASSERT_EQ(one.blocks.size(), many.blocks.size());
  expect_same_blocks(one, many, one.blocks.size(), "wide scan, 1 and 7 threads");
  EXPECT_EQ(one.beam_ids, many.beam_ids);
  EXPECT_EQ(one.hit_ids, many.hit_ids);
  // The working memory is kept between scans (as the mapper does): after the wide scan, scans of
  // other extents come out as from fresh memory.
  for (const int threads : {1, 3}) {
    ScanBuckets fresh;
    bucket_scan(grid, 0.2f, near, fresh, threads);
    const ScanObservations* scans[] = {&near, &far, &near};
    for (const ScanObservations* scan : scans) bucket_scan(grid, 0.2f, *scan, one, threads);
    ASSERT_EQ(fresh.blocks.size(), one.blocks.size());
    expect_same_blocks(fresh, one, fresh.blocks.size(), "reused working memory");
    EXPECT_EQ(fresh.beam_ids, one.beam_ids);
    EXPECT_EQ(fresh.hit_ids, one.hit_ids);
  }
}

// Bucketing decides edge and corner candidates in the beam's parameter space; here every block
// near the beams is checked against the plain segment-box distance, in both directions.
TEST(Bucketing, BeamBlocksAreExactlyThoseWithinReachOfTheSegment) {
  for (const BucketCase c : {BucketCase{0.1, 4, 0.2f}, BucketCase{0.2, 4, 0.6f}, BucketCase{0.1, 2, 0.35f}}) {
    GridParams gp;
    gp.resolution_m = c.resolution;
    gp.block_depth = c.depth;
    const Grid grid(gp);
    std::mt19937 rng(17 + c.depth);
    ScanObservations obs = random_observations(rng, 0, 400, 3.0f);
    // Axis-parallel and planar beams, where a direction component is exactly zero.
    obs.free_ends.push_back({obs.origin.x + 2.0f, obs.origin.y, obs.origin.z});
    obs.free_ends.push_back({obs.origin.x, obs.origin.y - 1.7f, obs.origin.z});
    obs.free_ends.push_back({obs.origin.x + 1.1f, obs.origin.y + 0.9f, obs.origin.z});
    obs.free_ends.push_back(obs.origin);  // zero length
    ScanBuckets buckets;
    bucket_scan(grid, c.radius, obs, buckets);
    const auto bucketed = bucketed_pairs(buckets, false);
    const double r2 = double(c.radius) * c.radius;
    const double bs = grid.block_size();
    std::set<std::pair<BlockKey, uint32_t>> expected;
    size_t near_misses = 0;
    for (uint32_t i = 0; i < obs.free_ends.size(); ++i) {
      const Vec3f& a = obs.origin;
      const Vec3f& b = obs.free_ends[i];
      auto block_range = [&](float p, float q, int32_t& k0, int32_t& k1) {
        k0 = static_cast<int32_t>(std::floor((std::min(p, q) - c.radius) / bs)) - 1;
        k1 = static_cast<int32_t>(std::floor((std::max(p, q) + c.radius) / bs)) + 1;
      };
      int32_t x0, x1, y0, y1, z0, z1;
      block_range(a.x, b.x, x0, x1);
      block_range(a.y, b.y, y0, y1);
      block_range(a.z, b.z, z0, z1);
      for (int32_t z = z0; z <= z1; ++z)
        for (int32_t y = y0; y <= y1; ++y)
          for (int32_t x = x0; x <= x1; ++x) {
            const double d2 = segment_box_dist2(a, b, grid.block_center_box({x, y, z}));
            if (std::fabs(d2 - r2) < 1e-9) continue;  // a tie: float corners vs double, either is right
            if (d2 < r2) expected.insert({BlockKey{x, y, z}, i});
            near_misses += d2 >= r2 && d2 < 1.5 * r2;
          }
    }
    EXPECT_GT(near_misses, 100u) << "the random beams should pass many blocks just out of reach";
    for (const auto& p : expected)
      EXPECT_TRUE(bucketed.count(p)) << "beam " << p.second << " missed block " << p.first.x << "," << p.first.y << ","
                                     << p.first.z;
    for (const auto& p : bucketed)
      EXPECT_TRUE(expected.count(p)) << "beam " << p.second << " put in block " << p.first.x << "," << p.first.y << ","
                                     << p.first.z << " out of reach";
  }
}

TEST(SegmentBoxDistance, KnownCases) {
  const Aabb box{{0, 0, 0}, {1, 1, 1}};
  EXPECT_DOUBLE_EQ(segment_box_dist2({-1, 0.5f, 0.5f}, {2, 0.5f, 0.5f}, box), 0.0);   // through
  EXPECT_DOUBLE_EQ(segment_box_dist2({-1, 2, 0.5f}, {2, 2, 0.5f}, box), 1.0);         // parallel above
  EXPECT_DOUBLE_EQ(segment_box_dist2({-3, 0.5f, 0.5f}, {-2, 0.5f, 0.5f}, box), 4.0);  // stops short
  EXPECT_NEAR(segment_box_dist2({2, 3, 0.5f}, {3, 2, 0.5f}, box), 4.5, 1e-12);        // diagonal past a corner edge
  EXPECT_DOUBLE_EQ(segment_box_dist2({2, 2, 2}, {2, 2, 2}, box), 3.0);                // zero length
}

}  // namespace
}  // namespace bgkmap
