// An open-addressing index from block keys to their numbers, the keys themselves kept by the
// caller in a vector (number i is keys[i]): linear probing in a power-of-two table of numbers, at
// most half full, Fibonacci hashing of BlockKeyHash. Shared by bucketing's per-scan numbering and
// the map's key -> slot lookup, where node-based std::unordered_map lookups cost a cache miss or
// two each. Private to the library.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "bgkmap/core/grid.hpp"

namespace bgkmap::key_table {

constexpr uint32_t kEmpty = ~uint32_t{0};

// A fresh table of `size` entries (a power of two), all empty.
inline void reset(std::vector<uint32_t>& table, size_t size) { table.assign(size, kEmpty); }

// The entry holding `key`'s number, or the empty entry where it would go. `table` is not empty.
inline size_t position(const std::vector<uint32_t>& table, const std::vector<BlockKey>& keys, const BlockKey& key) {
  const size_t mask = table.size() - 1;
  const int shift = 64 - __builtin_ctzll(table.size());
  // The top bits of the mixed key, so that every bit of it matters (a table of one entry: 0).
  size_t i = shift >= 64 ? 0
                         : static_cast<size_t>((static_cast<uint64_t>(BlockKeyHash{}(key)) * 0x9E3779B97F4A7C15ull) >>
                                               shift);
  for (;; i = (i + 1) & mask) {
    const uint32_t number = table[i];
    if (number == kEmpty || keys[number] == key) return i;
  }
}

// The number of `key`, or kEmpty.
inline uint32_t find(const std::vector<uint32_t>& table, const std::vector<BlockKey>& keys, const BlockKey& key) {
  return table.empty() ? kEmpty : table[position(table, keys, key)];
}

// Doubles the table, entries and all, when more than half of it would hold `entries` numbers
// (unchanged if that allocation fails).
inline void grow_for(std::vector<uint32_t>& table, const std::vector<BlockKey>& keys, size_t entries) {
  if (2 * entries <= table.size()) return;
  size_t size = table.size();
  while (2 * entries > size) size *= 2;
  std::vector<uint32_t> grown;
  reset(grown, size);
  for (const uint32_t number : table)
    if (number != kEmpty) grown[position(grown, keys, keys[number])] = number;
  table.swap(grown);
}

}  // namespace bgkmap::key_table
