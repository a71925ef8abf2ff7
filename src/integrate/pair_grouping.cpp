#include "integrate/pair_grouping.hpp"

#include <algorithm>

#include "core/parallel_errors.hpp"

namespace bgkmap {

void scatter(std::vector<PartPairs>& parts, const PartSplit& split, std::vector<BlockWork>& blocks,
             std::vector<uint32_t>& ids, uint32_t BlockWork::*begin, uint32_t BlockWork::*count) {
  size_t pairs = 0;
  for (int t = 0; t < split.parts; ++t) pairs += parts[static_cast<size_t>(t)].pairs.size();
  const int part_count = split.parts, team = team_for(pairs, split.team, kLightItemsPerThread);
  ParallelErrors errors;
#pragma omp parallel for num_threads(team) schedule(dynamic, 1)
  for (int t = 0; t < part_count; ++t)
    errors.run([&] {
      PartPairs& part = parts[static_cast<size_t>(t)];
      part.cursor.assign(blocks.size(), 0);
      for (const auto& [local, obs] : part.pairs) ++part.cursor[part.to_global[local]];
    });
  errors.rethrow();
  // Each block's range, then each part's start in it, in parallel over blocks: only the prefix
  // over blocks stays serial (serial blocks x parts steps grow with the threads: 64 parts on 16).
  const int64_t block_count = static_cast<int64_t>(blocks.size());
#pragma omp parallel for num_threads(team) schedule(static)
  for (int64_t b = 0; b < block_count; ++b) {
    uint32_t n = 0;
    for (int t = 0; t < part_count; ++t) n += parts[static_cast<size_t>(t)].cursor[static_cast<size_t>(b)];
    blocks[static_cast<size_t>(b)].*count = n;
  }
  uint32_t offset = 0;
  for (BlockWork& block : blocks) {
    block.*begin = offset;
    offset += block.*count;
  }
#pragma omp parallel for num_threads(team) schedule(static)
  for (int64_t b = 0; b < block_count; ++b) {
    uint32_t at = blocks[static_cast<size_t>(b)].*begin;
    for (int t = 0; t < part_count; ++t) {
      uint32_t& cursor = parts[static_cast<size_t>(t)].cursor[static_cast<size_t>(b)];
      const uint32_t n = cursor;
      cursor = at;
      at += n;
    }
  }
  ids.resize(offset);
#pragma omp parallel for num_threads(team) schedule(dynamic, 1)
  for (int t = 0; t < part_count; ++t) {
    PartPairs& part = parts[static_cast<size_t>(t)];
    for (const auto& [local, obs] : part.pairs) ids[part.cursor[part.to_global[local]]++] = obs;
  }
}

void sort_blocks_by_key(std::vector<BlockWork>& blocks, std::vector<uint32_t>& order, std::vector<BlockWork>& sorted) {
  order.resize(blocks.size());
  for (uint32_t k = 0; k < order.size(); ++k) order[k] = k;
  std::sort(order.begin(), order.end(), [&](uint32_t x, uint32_t y) { return blocks[x].key < blocks[y].key; });
  sorted.clear();
  for (uint32_t k : order) sorted.push_back(blocks[k]);
  blocks.swap(sorted);
}

}  // namespace bgkmap
