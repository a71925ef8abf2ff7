#include "integrate/key_numbering.hpp"

#include "core/parallel_errors.hpp"

namespace bgkmap {

void number_globally(std::vector<PartPairs>& parts, const PartSplit& split, KeyNumbering& global) {
  for (int t = 0; t < split.parts; ++t) {
    PartPairs& part = parts[static_cast<size_t>(t)];
    part.to_global.resize(part.keys.size());
    for (size_t k = 0; k < part.keys.size(); ++k) part.to_global[k] = global.index(part.keys[k]);
  }
}

namespace {

// The marked offsets of `dense` in memory order (z, y, x), then stable counting sorts by y and
// by x give key order (x, y, z).
void marked_in_key_order(const BlockWindow& window, const std::vector<uint32_t>& dense, std::vector<uint32_t>& present) {
  present.clear();
  for (size_t at = 0; at < window.size(); ++at)
    if (dense[at] != key_table::kEmpty) present.push_back(static_cast<uint32_t>(at));
  std::vector<uint32_t> by_y(present.size());
  auto counting_sort = [&](const std::vector<uint32_t>& from, std::vector<uint32_t>& to, uint32_t buckets,
                           auto bucket_of) {
    std::vector<uint32_t> start(buckets + 1, 0);
    for (uint32_t at : from) ++start[bucket_of(at) + 1];
    for (uint32_t b = 0; b < buckets; ++b) start[b + 1] += start[b];
    for (uint32_t at : from) to[start[bucket_of(at)]++] = at;
  };
  counting_sort(present, by_y, window.ny, [&](uint32_t at) { return window.y_index(at); });
  counting_sort(by_y, present, window.nx, [&](uint32_t at) { return window.x_index(at); });
}

}  // namespace

// Marking and mapping in parallel over parts: no serial numbering or sort (docs/ALGORITHM.md).
void number_in_key_order(std::vector<PartPairs>& hit_parts, const PartSplit& hit_split,
                         std::vector<PartPairs>& beam_parts, const PartSplit& beam_split, const BlockWindow& window,
                         std::vector<uint32_t>& dense, std::vector<uint32_t>& present, std::vector<BlockKey>& keys) {
  if (dense.size() < window.size()) dense.resize(window.size(), key_table::kEmpty);
  std::vector<PartPairs*> parts;
  for (int t = 0; t < hit_split.parts; ++t) parts.push_back(&hit_parts[static_cast<size_t>(t)]);
  for (int t = 0; t < beam_split.parts; ++t) parts.push_back(&beam_parts[static_cast<size_t>(t)]);
  size_t found = 0;
  for (const PartPairs* part : parts) found += part->keys.size();
  const int team = team_for(found, std::max(hit_split.team, beam_split.team), kLightItemsPerThread);
  const int64_t part_count = static_cast<int64_t>(parts.size());
  // Mark: parts finding the same block write the same value (atomic, so that is no data race).
#pragma omp parallel for num_threads(team) schedule(dynamic, 1)
  for (int64_t t = 0; t < part_count; ++t)
    for (const BlockKey& key : parts[static_cast<size_t>(t)]->keys)
      __atomic_store_n(&dense[window.offset(key)], 0u, __ATOMIC_RELAXED);
  marked_in_key_order(window, dense, present);
  keys.resize(present.size());
  for (uint32_t number = 0; number < present.size(); ++number) {
    dense[present[number]] = number;
    keys[number] = window.key_at(present[number]);
  }
  ParallelErrors errors;
#pragma omp parallel for num_threads(team) schedule(dynamic, 1)
  for (int64_t t = 0; t < part_count; ++t)
    errors.run([&] {
      PartPairs& part = *parts[static_cast<size_t>(t)];
      part.to_global.resize(part.keys.size());
      for (size_t k = 0; k < part.keys.size(); ++k) part.to_global[k] = dense[window.offset(part.keys[k])];
    });
  errors.rethrow();
  for (uint32_t at : present) dense[at] = key_table::kEmpty;
}

}  // namespace bgkmap
