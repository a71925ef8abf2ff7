// How bucketing cuts one scan's observations into parts that threads take in turn, and what
// each part keeps: its blocks numbered locally and its (block, observation) pairs in input order.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "bgkmap/core/grid.hpp"

namespace bgkmap {

// One part's pairs of one kind (hits or beams: a contiguous range of them).
struct PartPairs {
  std::vector<BlockKey> keys;                        // local block number -> key
  std::vector<uint32_t> table;                       // open-addressing index over keys
  std::vector<uint32_t> dense;                       // index over the keys in the scan's window
  std::vector<std::pair<uint32_t, uint32_t>> pairs;  // (local block number, observation)
  std::vector<uint32_t> to_global;                   // local -> global block number
  std::vector<uint32_t> cursor;                      // per global block: where the next pair goes
};

// How one kind of observation was split: `parts` contiguous ranges run on `team` threads.
struct PartSplit {
  int team = 1, parts = 1;
};

// Dense arrays of all parts together stay within this many entries (64 MB); a scan whose window
// would take more hashes all its keys.
constexpr size_t kDenseEntriesBudget = size_t(1) << 24;

// Threads worth starting for `count` items of about `per_thread` each: one per `per_thread`
// items, at most `threads`. Every parallel region costs a wake-up and a barrier (tens of
// microseconds with passive waiting, a scheduler time slice when a core is busy with another
// process), so the light loops (a few nanoseconds an item) stay on one thread for small scans.
constexpr size_t kHeavyItemsPerThread = 256;    // observations searched for their blocks
constexpr size_t kPairItemsPerThread = 4096;    // pairs given their block-frame geometry
constexpr size_t kLightItemsPerThread = 32768;  // keys and pairs counted, numbered or moved
inline int team_for(size_t count, int threads, size_t per_thread = kHeavyItemsPerThread) {
  return std::max(1, std::min<int>(threads, static_cast<int>(count / per_thread) + 1));
}

}  // namespace bgkmap
