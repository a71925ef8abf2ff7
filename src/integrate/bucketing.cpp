#include "bgkmap/integrate/bucketing.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "bgkmap/core/memory_limit.hpp"
#include "integrate/block_window.hpp"
#include "integrate/bucket_scratch.hpp"
#include "integrate/local_frames.hpp"
#include "integrate/observation_reach.hpp"
#include "integrate/pair_grouping.hpp"

namespace bgkmap {

ScanBuckets::Scratch::Scratch() = default;
ScanBuckets::Scratch::Scratch(const Scratch&) {}
ScanBuckets::Scratch& ScanBuckets::Scratch::operator=(const Scratch&) { return *this; }
ScanBuckets::Scratch::Scratch(Scratch&&) noexcept = default;
ScanBuckets::Scratch& ScanBuckets::Scratch::operator=(Scratch&&) noexcept = default;
ScanBuckets::Scratch::~Scratch() = default;

BucketScratch& ScanBuckets::Scratch::get() {
  if (!memory_) memory_ = std::make_unique<BucketScratch>();
  return *memory_;
}

namespace {

// Bytes of one (block, observation) pair across bucketing's arrays: its (block, id) entry in the
// part's pairs, its id, and its block-local record.
constexpr double kHitPairBytes = 8 + 4 + sizeof(LocalHit);
constexpr double kBeamPairBytes = 8 + 4 + sizeof(LocalBeam);

// Refuses a scan whose pairs would not fit the memory limit, before finding them. Pairs are
// estimated by volume: a hit meets about (1 + 2 r / block)^3 blocks, a free segment of length L
// (1 + 2 r / block)^2 (1 + sqrt(3) L / block), sqrt(3) for a diagonal one; what the arrays hold
// from the last scan is reused.
void require_pair_memory(const Grid& grid, float support_radius_m, const ScanObservations& obs,
                         const ScanBuckets& out, const char* reach_flag) {
  const double bs = grid.block_size(), across = 1 + 2 * support_radius_m / bs;
  double beam_pairs = 0, longest = 0;
  for (const Vec3f& end : obs.free_ends) {
    const double dx = end.x - obs.origin.x, dy = end.y - obs.origin.y, dz = end.z - obs.origin.z;
    const double length = std::sqrt(dx * dx + dy * dy + dz * dz);
    longest = std::max(longest, length);
    beam_pairs += 1 + 1.7320508075688772 * length / bs;
  }
  beam_pairs *= across * across;
  const double hit_pairs = double(obs.hits.size()) * across * across * across;
  const double held = double(out.hit_ids.capacity()) * kHitPairBytes + double(out.beam_ids.capacity()) * kBeamPairBytes;
  const double needed = hit_pairs * kHitPairBytes + beam_pairs * kBeamPairBytes - held;
  if (needed <= 0) return;
  char what[160];
  std::snprintf(what, sizeof what, "bucketing a scan (%zu hits, %zu beams up to %.0f m: about %.3g block pairs)",
                obs.hits.size(), obs.free_ends.size(), longest, hit_pairs + beam_pairs);
  require_memory(needed, what,
                 std::string("give a shorter --max-range, a smaller ") + reach_flag +
                     " or a coarser --ds (or raise --max-memory)");
}

}  // namespace

// Finds each observation's blocks in parallel parts (hits and beams are independent), numbers
// the blocks in key order, groups the pairs by block in input order, then writes each pair's
// geometry in its block's frame. Every step's result is independent of the thread count.
void bucket_scan(const Grid& grid, float support_radius_m, const ScanObservations& obs, ScanBuckets& out,
                 int threads, const char* reach_flag) {
  require_pair_memory(grid, support_radius_m, obs, out, reach_flag);
  // Only the blocks start empty. The id and geometry arrays are resized and every element is
  // written; keeping the last scan's sizes spares zero-filling tens of MB per scan in one thread.
  out.blocks.clear();
  BucketScratch& scratch = out.scratch.get();
  const BlockReach reach(grid, support_radius_m);
  const BlockWindow window = scan_window(reach, obs, kDenseEntriesBudget / 2);

  const HitBlocks hit_blocks(grid, reach);
  const PartSplit hit_split = find_pairs(obs.hits.size(), threads, window, scratch.hits,
                                         [&](uint32_t i, const auto& emit) { hit_blocks(obs.hits[i], emit); });
  const BeamBlocks beam_blocks(reach, obs.origin);
  const PartSplit beam_split = find_pairs(obs.free_ends.size(), threads, window, scratch.beams,
                                          [&](uint32_t i, const auto& emit) { beam_blocks(obs.free_ends[i], emit); });

  const bool in_key_order = window.size() > 0;
  if (in_key_order) {
    number_in_key_order(scratch.hits, hit_split, scratch.beams, beam_split, window, scratch.dense, scratch.order,
                        scratch.keys);
  } else {
    KeyNumbering global(scratch.keys, scratch.table, scratch.dense, window);
    number_globally(scratch.hits, hit_split, global);
    number_globally(scratch.beams, beam_split, global);
  }
  out.blocks.resize(scratch.keys.size());
  for (size_t b = 0; b < scratch.keys.size(); ++b) out.blocks[b].key = scratch.keys[b];
  scatter(scratch.hits, hit_split, out.blocks, out.hit_ids, &BlockWork::hit_begin, &BlockWork::hit_count);
  scatter(scratch.beams, beam_split, out.blocks, out.beam_ids, &BlockWork::beam_begin, &BlockWork::beam_count);
  if (!in_key_order) sort_blocks_by_key(out.blocks, scratch.order, scratch.sorted);

  write_local_frames(grid, obs, out, scratch.lines,
                     team_for(obs.free_ends.size(), beam_split.team, kLightItemsPerThread),
                     team_for(out.hit_ids.size() + out.beam_ids.size(), threads, kPairItemsPerThread));
}

void keep_layer_blocks(ScanBuckets& buckets, int32_t block_z) {
  std::vector<BlockWork>& blocks = buckets.blocks;
  blocks.erase(std::remove_if(blocks.begin(), blocks.end(), [&](const BlockWork& w) { return w.key.z != block_z; }),
               blocks.end());
}

}  // namespace bgkmap
