// Cutting a scan's block work into launches (plain host code of the OpenCL back end): every
// observation of every block in exactly one job, in order, within the limits.
#include <gtest/gtest.h>

#include <cstring>
#include <random>

#include "integrate/beam_rows_8.hpp"
#include "integrate/opencl/launch_plan.hpp"

namespace bgkmap::opencl_detail {
namespace {

// Blocks with the given hit and beam counts; observation k of the scan is LocalHit{k, k, k} and
// LocalBeam{k, ...}, so gathered data shows where it came from.
ScanBuckets make_buckets(const std::vector<std::pair<uint32_t, uint32_t>>& counts) {
  ScanBuckets b;
  for (size_t i = 0; i < counts.size(); ++i) {
    BlockWork w;
    w.key = {int32_t(i), 0, 0};
    w.slot = uint32_t(100 + i);
    w.hit_begin = uint32_t(b.hits.size());
    w.hit_count = counts[i].first;
    w.beam_begin = uint32_t(b.beams.size());
    w.beam_count = counts[i].second;
    for (uint32_t k = 0; k < w.hit_count; ++k) {
      const float v = float(b.hits.size());
      b.hits.push_back({v, v, v});
    }
    for (uint32_t k = 0; k < w.beam_count; ++k) {
      const float v = float(b.beams.size());
      b.beams.push_back({v, v, v, 0, 0, 0, 0, v});
    }
    b.blocks.push_back(w);
  }
  return b;
}

// Gathers every launch and checks that each block's observations arrive whole and in order.
void check_plan(const ScanBuckets& b, const LaunchLimits& limits) {
  std::vector<WorkPiece> pieces;
  std::vector<Launch> launches;
  plan_launches(b, limits, pieces, launches);
  std::vector<uint32_t> hits_seen(b.blocks.size(), 0), beams_seen(b.blocks.size(), 0);
  size_t next_piece = 0;
  for (const Launch& launch : launches) {
    ASSERT_EQ(launch.first_piece, next_piece);
    ASSERT_GT(launch.piece_count, 0u);
    ASSERT_LE(launch.piece_count, limits.max_jobs);
    ASSERT_LE(launch.hits, limits.max_hits);
    ASSERT_LE(launch.beams, limits.max_beams);
    next_piece += launch.piece_count;
    std::vector<DeviceJob> jobs(launch.piece_count);
    std::vector<LocalHit> hits(launch.hits);
    std::vector<LocalBeam> beams(launch.beams);
    gather_launch(b, pieces, launch, jobs.data(), hits.data(), beams.data());
    for (size_t j = 0; j < jobs.size(); ++j) {
      const WorkPiece& p = pieces[launch.first_piece + j];
      const BlockWork& w = b.blocks[p.block];
      EXPECT_EQ(jobs[j].slot, w.slot);
      ASSERT_EQ(p.hit_offset, hits_seen[p.block]) << "pieces of a block out of order";
      ASSERT_EQ(p.beam_offset, beams_seen[p.block]);
      for (uint32_t k = 0; k < jobs[j].hit_count; ++k)
        ASSERT_EQ(hits[jobs[j].hit_begin + k].x, float(w.hit_begin + p.hit_offset + k));
      for (uint32_t k = 0; k < jobs[j].beam_count; ++k)
        ASSERT_EQ(beams[jobs[j].beam_begin + k].s_max, float(w.beam_begin + p.beam_offset + k));
      hits_seen[p.block] += jobs[j].hit_count;
      beams_seen[p.block] += jobs[j].beam_count;
    }
  }
  EXPECT_EQ(next_piece, pieces.size());
  for (size_t i = 0; i < b.blocks.size(); ++i) {
    EXPECT_EQ(hits_seen[i], b.blocks[i].hit_count) << "block " << i;
    EXPECT_EQ(beams_seen[i], b.blocks[i].beam_count) << "block " << i;
  }
}

TEST(LaunchPlan, GatheringOnSeveralThreadsWritesTheSameLaunch) {
  // Hundreds of blocks of random sizes, so that each thread gathers many; the row bits of real
  // beams through the blocks, so that they differ from beam to beam.
  std::mt19937 rng(5);
  std::uniform_int_distribution<uint32_t> count(0, 40);
  std::vector<std::pair<uint32_t, uint32_t>> counts(700);
  for (auto& c : counts) c = {count(rng), 1 + count(rng)};
  ScanBuckets b = make_buckets(counts);
  std::uniform_real_distribution<float> coordinate(-0.4f, 1.2f);
  for (LocalBeam& beam : b.beams) {
    const float s_max = beam.s_max;
    beam = {coordinate(rng), coordinate(rng), coordinate(rng), 0.6f, 0.0f, 0.8f, 0.0f, 1.0f};
    beam.s_max = std::fmod(s_max, 2.0f);
  }
  const RowReach8 reach = RowReach8::make(0.1f, 0.2f);
  std::vector<WorkPiece> pieces;
  std::vector<Launch> launches;
  plan_launches(b, {300, 4000, 6000}, pieces, launches);
  ASSERT_GT(launches.size(), 1u);
  for (const Launch& launch : launches) {
    std::vector<DeviceJob> jobs1(launch.piece_count), jobs4(launch.piece_count);
    std::vector<LocalHit> hits1(launch.hits), hits4(launch.hits);
    std::vector<LocalBeam> beams1(launch.beams), beams4(launch.beams);
    std::vector<uint64_t> rows1(launch.beams), rows4(launch.beams, ~uint64_t(0));
    gather_launch(b, pieces, launch, jobs1.data(), hits1.data(), beams1.data(), &reach, rows1.data(), 1);
    gather_launch(b, pieces, launch, jobs4.data(), hits4.data(), beams4.data(), &reach, rows4.data(), 4);
    EXPECT_EQ(0, std::memcmp(jobs1.data(), jobs4.data(), jobs1.size() * sizeof(DeviceJob)));
    EXPECT_EQ(0, std::memcmp(hits1.data(), hits4.data(), hits1.size() * sizeof(LocalHit)));
    EXPECT_EQ(0, std::memcmp(beams1.data(), beams4.data(), beams1.size() * sizeof(LocalBeam)));
    EXPECT_EQ(rows1, rows4);
    size_t beams_with_rows = 0;
    for (size_t k = 0; k < rows1.size(); ++k) {
      EXPECT_EQ(rows1[k], beam_row_mask_8(reach, beams1[k])) << "beam " << k;
      beams_with_rows += rows1[k] != 0;
    }
    EXPECT_GT(beams_with_rows, 0u);
  }
}

TEST(LaunchPlan, EverythingInOneLaunchWhenItFits) {
  const ScanBuckets b = make_buckets({{3, 5}, {0, 7}, {4, 0}});
  std::vector<WorkPiece> pieces;
  std::vector<Launch> launches;
  plan_launches(b, {100, 100, 100}, pieces, launches);
  ASSERT_EQ(launches.size(), 1u);
  EXPECT_EQ(pieces.size(), 3u);  // one piece per block
  EXPECT_EQ(launches[0].hits, 7u);
  EXPECT_EQ(launches[0].beams, 12u);
  check_plan(b, {100, 100, 100});
}

TEST(LaunchPlan, NoBlocksNoLaunches) {
  std::vector<WorkPiece> pieces;
  std::vector<Launch> launches;
  plan_launches(ScanBuckets{}, {4, 4, 4}, pieces, launches);
  EXPECT_TRUE(launches.empty());
  EXPECT_TRUE(pieces.empty());
}

TEST(LaunchPlan, JobLimitStartsNewLaunches) {
  const ScanBuckets b = make_buckets({{1, 1}, {1, 1}, {1, 1}, {1, 1}, {1, 1}});
  std::vector<WorkPiece> pieces;
  std::vector<Launch> launches;
  plan_launches(b, {2, 100, 100}, pieces, launches);
  EXPECT_EQ(launches.size(), 3u);
  check_plan(b, {2, 100, 100});
}

TEST(LaunchPlan, BlocksLargerThanALaunchAreCut) {
  const ScanBuckets b = make_buckets({{25, 3}, {2, 40}, {0, 1}, {9, 9}});
  check_plan(b, {3, 4, 6});
  check_plan(b, {1, 1, 1});
  check_plan(b, {100, 25, 40});
}

TEST(LaunchPlan, RandomBlocksAndLimits) {
  std::mt19937 rng(3);
  std::uniform_int_distribution<uint32_t> count(0, 30), limit(1, 40);
  for (int round = 0; round < 200; ++round) {
    std::vector<std::pair<uint32_t, uint32_t>> counts(1 + count(rng) % 12);
    for (auto& c : counts) {
      c = {count(rng), count(rng)};
      if (c.first + c.second == 0) c.second = 1;  // bucketing never makes an empty block
    }
    check_plan(make_buckets(counts), {limit(rng), limit(rng), limit(rng)});
  }
}

}  // namespace
}  // namespace bgkmap::opencl_detail
