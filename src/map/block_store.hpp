// Blocks of cells by key, for every map that keeps per-cell state in the block grid: BlockIndex
// numbers block keys in the order they were first seen (their slots), BlockStore<T> keeps
// cells_per_block values of T per slot in one contiguous vector. BgkMap uses the index over its
// own pool (CellPool, mirrored on devices); methods with other cell states use the store.
// Private to the library.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/core/memory_limit.hpp"
#include "core/key_table.hpp"

namespace bgkmap {

class BlockIndex {
 public:
  static constexpr uint32_t kAbsent = key_table::kEmpty;

  BlockIndex() { key_table::reset(table_, 1024); }

  // The slot of `key`, or kAbsent.
  uint32_t find(const BlockKey& key) const { return key_table::find(table_, keys_, key); }

  // The slot of `key`, numbered next when new; a new key is recorded only after `make_room()`
  // returns (it grows the caller's storage), so a throw there leaves the index as it was.
  template <typename MakeRoom>
  uint32_t find_or_insert(const BlockKey& key, MakeRoom&& make_room) {
    const size_t at = key_table::position(table_, keys_, key);
    if (table_[at] != kAbsent) return table_[at];
    make_room();
    const uint32_t slot = static_cast<uint32_t>(keys_.size());
    keys_.push_back(key);
    table_[at] = slot;
    key_table::grow_for(table_, keys_, keys_.size());
    return slot;
  }

  size_t size() const { return keys_.size(); }
  const BlockKey& key(uint32_t slot) const { return keys_[slot]; }

 private:
  std::vector<uint32_t> table_;  // key -> slot, open addressing over keys_
  std::vector<BlockKey> keys_;
};

template <typename T>
class BlockStore {
 public:
  // `initial`: the value of every cell of a new block.
  explicit BlockStore(const Grid& grid, T initial = T{}) : grid_(grid), initial_(initial) {}

  // Throws MemoryLimitExceeded (core/memory_limit.hpp) before growing beyond the memory limit.
  uint32_t ensure_slot(const BlockKey& key) {
    return index_.find_or_insert(key, [&] {
      const size_t needed = cells_.size() + grid_.cells_per_block();
      if (needed > cells_.capacity())
        cells_.reserve(grown_capacity(cells_.capacity(), needed, sizeof(T),
                                      "the map's cells (" + format_bytes(double(cells_.size() * sizeof(T))) +
                                          " so far)",
                                      "give a coarser --resolution or a shorter --max-range (or raise --max-memory)"));
      cells_.resize(needed, initial_);
    });
  }
  uint32_t find_slot(const BlockKey& key) const { return index_.find(key); }

  T* block(uint32_t slot) { return cells_.data() + static_cast<size_t>(slot) * grid_.cells_per_block(); }
  const T* block(uint32_t slot) const { return cells_.data() + static_cast<size_t>(slot) * grid_.cells_per_block(); }

  // The cell's value, or nullptr where its block was never touched.
  const T* find(const CellIndex& cell) const {
    const uint32_t slot = find_slot(grid_.block_of(cell));
    return slot == BlockIndex::kAbsent ? nullptr : block(slot) + grid_.local_index(cell);
  }

  size_t block_count() const { return index_.size(); }
  const BlockKey& key_of_slot(uint32_t slot) const { return index_.key(slot); }
  // Every cell of every block, slot by slot (slot s: [s * cells_per_block, (s+1) * cells_per_block)).
  const std::vector<T>& cells() const { return cells_; }

  // visit(cell index, value) for every cell of every touched block, in slot order.
  template <typename Visit>
  void for_each_cell(Visit&& visit) const {
    const int n = grid_.cells_per_block();
    for (uint32_t slot = 0; slot < block_count(); ++slot) {
      const T* values = block(slot);
      for (int local = 0; local < n; ++local) visit(grid_.cell_at(key_of_slot(slot), local), values[local]);
    }
  }

 private:
  Grid grid_;
  T initial_;
  BlockIndex index_;
  std::vector<T> cells_;
};

}  // namespace bgkmap
