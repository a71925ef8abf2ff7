// Finding each observation's blocks in parallel parts and grouping the (block, observation)
// pairs by block, so that each block gets its observations in input order whatever the threads.
#pragma once

#include <vector>

#include "bgkmap/integrate/bucketing.hpp"
#include "core/parallel_errors.hpp"
#include "integrate/block_window.hpp"
#include "integrate/bucket_parts.hpp"
#include "integrate/key_numbering.hpp"

namespace bgkmap {

// Runs find(i, emit) for every observation i < count, where find calls emit(key) for each block
// that observation reaches. The observations are cut into contiguous parts (four per thread,
// taken dynamically, so a thread slowed by a busy core does not hold the others up); each part
// numbers the blocks it finds locally and keeps its pairs in input order.
template <class Find>
PartSplit find_pairs(size_t count, int threads, const BlockWindow& window, std::vector<PartPairs>& parts,
                     const Find& find) {
  PartSplit split;
  split.team = team_for(count, threads);
  split.parts = split.team == 1 ? 1 : 4 * split.team;
  if (parts.size() < static_cast<size_t>(split.parts)) parts.resize(static_cast<size_t>(split.parts));
  // A quarter of the budget for each kind's parts, half for the global numbering.
  const BlockWindow dense = window.size() * split.parts <= kDenseEntriesBudget / 4 ? window : BlockWindow{};
  const int64_t n = static_cast<int64_t>(count);
  ParallelErrors errors;
#pragma omp parallel for num_threads(split.team) schedule(dynamic, 1)
  for (int t = 0; t < split.parts; ++t)
    errors.run([&] {
      PartPairs& mine = parts[static_cast<size_t>(t)];
      KeyNumbering local(mine.keys, mine.table, mine.dense, dense);
      mine.pairs.clear();
      for (int64_t i = n * t / split.parts; i < n * (t + 1) / split.parts; ++i) {
        const uint32_t obs = static_cast<uint32_t>(i);
        find(obs, [&](const BlockKey& key) { mine.pairs.emplace_back(local.index(key), obs); });
      }
    });
  errors.rethrow();
  return split;
}

// Writes the observation ids of one kind grouped by block (CSR ranges through the members):
// a counting sort whose counts and placement run per part, in parallel. Within a block, part
// t's pairs follow those of the parts before it, and each part's are in input order, so the
// result is the same as sorting the concatenated pairs stably.
void scatter(std::vector<PartPairs>& parts, const PartSplit& split, std::vector<BlockWork>& blocks,
             std::vector<uint32_t>& ids, uint32_t BlockWork::*begin, uint32_t BlockWork::*count);

// Puts blocks numbered in order of first appearance in key order (deterministic); `order` and
// `sorted` are working memory.
void sort_blocks_by_key(std::vector<BlockWork>& blocks, std::vector<uint32_t>& order, std::vector<BlockWork>& sorted);

}  // namespace bgkmap
