// Numbering the blocks one scan reaches: each part of the scan numbers its blocks locally, then
// the parts' numbers are mapped to the scan's (in key order where the scan has a window).
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include "core/key_table.hpp"
#include "integrate/block_window.hpp"
#include "integrate/bucket_parts.hpp"

namespace bgkmap {

// Numbers block keys in order of first appearance. Keys inside the window are looked up in a
// dense array (`dense`: all kEmpty between uses, which the destructor restores); others in a
// key_table (open addressing). Hashing spread a beam's neighbouring blocks over the table: its
// probes and key compares were a quarter of bucketing (perf, 1 thread).
class KeyNumbering {
 public:
  KeyNumbering(std::vector<BlockKey>& keys, std::vector<uint32_t>& table, std::vector<uint32_t>& dense,
               const BlockWindow& window)
      : keys_(keys), table_(table), dense_(dense), window_(window) {
    keys_.clear();
    if (dense_.size() < window_.size()) dense_.resize(window_.size(), kEmpty);
    // The size the last scan grew the table to: scans are alike, so it rarely grows again.
    key_table::reset(table_, std::max<size_t>(1024, table_.size()));
  }
  ~KeyNumbering() {
    for (const BlockKey& key : keys_)
      if (window_.contains(key)) dense_[window_.offset(key)] = kEmpty;
  }
  KeyNumbering(const KeyNumbering&) = delete;
  KeyNumbering& operator=(const KeyNumbering&) = delete;

  uint32_t index(const BlockKey& key) {
    const bool in_window = window_.contains(key);
    uint32_t& number = in_window ? dense_[window_.offset(key)] : table_[key_table::position(table_, keys_, key)];
    if (number != kEmpty) return number;
    number = static_cast<uint32_t>(keys_.size());
    keys_.push_back(key);
    if (!in_window) key_table::grow_for(table_, keys_, ++hashed_);  // `number` may move
    return static_cast<uint32_t>(keys_.size() - 1);
  }

 private:
  static constexpr uint32_t kEmpty = key_table::kEmpty;

  std::vector<BlockKey>& keys_;
  std::vector<uint32_t>& table_;
  std::vector<uint32_t>& dense_;
  const BlockWindow window_;
  size_t hashed_ = 0;  // keys in table_
};

// Global block numbers for the locally numbered blocks of the parts, in part order, so that
// blocks are numbered in order of first appearance in the concatenated pairs.
void number_globally(std::vector<PartPairs>& parts, const PartSplit& split, KeyNumbering& global);

// With a window: every block any part of either kind found, numbered in key order into `keys`,
// so that the blocks need no sort afterwards, and each part's local numbers mapped to those.
// `dense` is all kEmpty before and after; `present` is working memory.
void number_in_key_order(std::vector<PartPairs>& hit_parts, const PartSplit& hit_split,
                         std::vector<PartPairs>& beam_parts, const PartSplit& beam_split, const BlockWindow& window,
                         std::vector<uint32_t>& dense, std::vector<uint32_t>& present, std::vector<BlockKey>& keys);

}  // namespace bgkmap
