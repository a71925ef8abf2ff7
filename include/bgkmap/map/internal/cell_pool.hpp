// The map's cells: one contiguous array (slot s owns [s * cells_per_block, (s+1) * cells_per_block),
// copied to and from OpenCL devices in one transfer) that grows without copying what it holds.
//
// A std::vector doubles by allocating a new array, copying every cell and freeing the old one,
// so each growth touches fresh pages twice; on a virtual machine the page faults made growing
// the map as costly as a third of the pair evaluation of a small scan. Here the array is an
// anonymous mapping that grows with mremap: the kernel moves page tables, cells stay where
// they are in physical memory, and only the new cells are touched. Where mremap is missing the
// pool falls back to allocate-and-copy.
#pragma once

#include <cstddef>

#include "bgkmap/core/bgk_layout.h"

namespace bgkmap {

// Plain-data cell, the same layout on host and device (core/bgk_layout.h).
using Cell = ::BgkCell;

class CellPool {
 public:
  CellPool() = default;
  CellPool(const CellPool& other);
  CellPool& operator=(const CellPool& other);
  CellPool(CellPool&& other) noexcept;
  CellPool& operator=(CellPool&& other) noexcept;
  ~CellPool();

  size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  Cell* data() { return cells_; }
  const Cell* data() const { return cells_; }
  Cell& operator[](size_t i) { return cells_[i]; }
  const Cell& operator[](size_t i) const { return cells_[i]; }
  Cell* begin() { return cells_; }
  Cell* end() { return cells_ + size_; }
  const Cell* begin() const { return cells_; }
  const Cell* end() const { return cells_ + size_; }

  // Appends `count` cells set to `value`.
  void append(size_t count, const Cell& value);
  void clear() { size_ = 0; }

 private:
  void grow_to(size_t min_capacity);
  void release();

  Cell* cells_ = nullptr;
  size_t size_ = 0;
  size_t capacity_ = 0;  // cells
};

}  // namespace bgkmap
