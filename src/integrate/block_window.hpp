// Which blocks lie within reach of an interval, and the box of blocks one scan can reach.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/integrate/observations.hpp"

namespace bgkmap {

// The blocks along one axis whose cell-centre interval, grown by the support radius r, meets
// [lo, hi]: block k's centres span [k bs + h, (k+1) bs - h], h = half a cell. Padded by a hair;
// the exact distance tests decide.
struct BlockReach {
  double bs;   // block size
  double h;    // half a cell
  double r;    // support radius
  double pad;  // 1e-9 blocks

  BlockReach(const Grid& grid, double support_radius_m)
      : bs(grid.block_size()), h(0.5 * grid.resolution()), r(support_radius_m), pad(1e-9 * grid.block_size()) {}

  // False also when a bound is not a finite block number of 32 bits (nothing there can be mapped).
  bool span(double lo, double hi, int32_t& k0, int32_t& k1) const {
    const double first = std::ceil((lo + h - r - pad) / bs - 1.0), last = std::floor((hi - h + r + pad) / bs);
    constexpr double kLimit = 2147483647.0;
    if (!(first >= -kLimit && first <= kLimit && last >= -kLimit && last <= kLimit)) return false;
    k0 = static_cast<int32_t>(first);
    k1 = static_cast<int32_t>(last);
    return k0 <= k1;
  }
};

// A box of block keys, so that the numbers of the blocks in it can be kept in a dense array.
// Keys outside it still work (they are hashed).
struct BlockWindow {
  int32_t x0 = 0, y0 = 0, z0 = 0;
  uint32_t nx = 0, ny = 0, nz = 0;  // all 0: no window

  size_t size() const { return size_t(nx) * ny * nz; }
  bool contains(const BlockKey& k) const {
    return uint32_t(k.x - x0) < nx && uint32_t(k.y - y0) < ny && uint32_t(k.z - z0) < nz;
  }
  // x fastest: the blocks a beam visits one after another along a row are neighbours here.
  size_t offset(const BlockKey& k) const {
    return (size_t(uint32_t(k.z - z0)) * ny + uint32_t(k.y - y0)) * nx + uint32_t(k.x - x0);
  }
  // The inverse of offset().
  uint32_t x_index(size_t at) const { return static_cast<uint32_t>(at % nx); }
  uint32_t y_index(size_t at) const { return static_cast<uint32_t>((at / nx) % ny); }
  BlockKey key_at(size_t at) const {
    return {x0 + static_cast<int32_t>(x_index(at)), y0 + static_cast<int32_t>(y_index(at)),
            z0 + static_cast<int32_t>(at / (size_t(nx) * ny))};
  }
};

// The blocks within reach of the scan's extent (origin, hits and beam ends), padded by one block
// against rounding, so that every block the scan reaches lies inside; no window (size 0) when
// that box would hold more than `max_blocks`.
BlockWindow scan_window(const BlockReach& reach, const ScanObservations& obs, size_t max_blocks);

}  // namespace bgkmap
