// Integer coordinates of cells and blocks, and the conversions between them and metres.
//
// Conventions (docs/DESIGN.md): a cell's global index is floor(x / resolution) per axis, so cell
// (i, j, k) covers [i*r, (i+1)*r) and its centre is (i + 0.5) * r -- the same cells as OctoMap's
// keys at that resolution. A block holds n = 2^(depth-1) cells per side; block index =
// floor(cell index / n); cells inside a block are numbered x fastest: lx + n*(ly + n*lz).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>

#include "bgkmap/core/params.hpp"

namespace bgkmap {

struct Vec3f {
  float x = 0, y = 0, z = 0;
};

struct Vec3d {
  double x = 0, y = 0, z = 0;
};

struct CellIndex {
  int32_t x = 0, y = 0, z = 0;
  bool operator==(const CellIndex& o) const { return x == o.x && y == o.y && z == o.z; }
};

struct BlockKey {
  int32_t x = 0, y = 0, z = 0;
  bool operator==(const BlockKey& o) const { return x == o.x && y == o.y && z == o.z; }
  bool operator!=(const BlockKey& o) const { return !(*this == o); }
  bool operator<(const BlockKey& o) const {
    return x != o.x ? x < o.x : (y != o.y ? y < o.y : z < o.z);
  }
};

struct BlockKeyHash {
  size_t operator()(const BlockKey& k) const {
    // Large odd multipliers spread neighbouring blocks across buckets.
    uint64_t h = static_cast<uint64_t>(static_cast<uint32_t>(k.x)) * 0x9E3779B97F4A7C15ull;
    h ^= static_cast<uint64_t>(static_cast<uint32_t>(k.y)) * 0xC2B2AE3D27D4EB4Full + (h >> 29);
    h ^= static_cast<uint64_t>(static_cast<uint32_t>(k.z)) * 0x165667B19E3779F9ull + (h >> 31);
    return static_cast<size_t>(h);
  }
};

// Axis-aligned box in metres.
struct Aabb {
  Vec3f min, max;
};

inline int32_t floor_div(int32_t a, int32_t b) {
  const int32_t q = a / b;
  return (a % b != 0 && ((a < 0) != (b < 0))) ? q - 1 : q;
}

// What the 32-bit cell and block keys can hold. Points farther than kCoordinateLimitM from the
// origin on any axis are dropped and counted (PreprocessCounts::dropped_out_of_key_range), queries
// there refused; resolutions below kMinResolutionM are refused (BuildParams::validate). Together
// they keep every cell index within 2^30, so that block and neighbour arithmetic cannot overflow.
constexpr double kCoordinateLimitM = 1e6;
constexpr double kMinResolutionM = 1e-3;
constexpr double kMaxResolutionM = 1e4;  // cells wider than 10 km map nothing useful
inline bool within_key_range(double x, double y, double z) {
  return std::abs(x) <= kCoordinateLimitM && std::abs(y) <= kCoordinateLimitM && std::abs(z) <= kCoordinateLimitM;
}

// Cell and block arithmetic for one grid geometry.
class Grid {
 public:
  explicit Grid(const GridParams& params)
      : resolution_(params.resolution_m), n_(params.cells_per_side()) {}

  double resolution() const { return resolution_; }
  int cells_per_side() const { return n_; }
  int cells_per_block() const { return n_ * n_ * n_; }
  double block_size() const { return resolution_ * n_; }

  CellIndex cell_of(double x, double y, double z) const {
    return {static_cast<int32_t>(std::floor(x / resolution_)),
            static_cast<int32_t>(std::floor(y / resolution_)),
            static_cast<int32_t>(std::floor(z / resolution_))};
  }
  BlockKey block_of(const CellIndex& c) const {
    return {floor_div(c.x, n_), floor_div(c.y, n_), floor_div(c.z, n_)};
  }
  BlockKey block_of(double x, double y, double z) const { return block_of(cell_of(x, y, z)); }

  // Index of a cell inside its block (x fastest).
  int local_index(const CellIndex& c) const {
    const BlockKey b = block_of(c);
    return (c.x - b.x * n_) + n_ * ((c.y - b.y * n_) + n_ * (c.z - b.z * n_));
  }
  CellIndex cell_at(const BlockKey& b, int local) const {
    return {b.x * n_ + local % n_, b.y * n_ + (local / n_) % n_, b.z * n_ + local / (n_ * n_)};
  }

  Vec3f cell_center(const CellIndex& c) const {
    return {static_cast<float>((c.x + 0.5) * resolution_), static_cast<float>((c.y + 0.5) * resolution_),
            static_cast<float>((c.z + 0.5) * resolution_)};
  }
  // Exact centre (double): the reference for every float computation relative to it.
  Vec3d cell_center_d(const CellIndex& c) const {
    return {(c.x + 0.5) * resolution_, (c.y + 0.5) * resolution_, (c.z + 0.5) * resolution_};
  }
  Vec3d block_first_center_d(const BlockKey& b) const { return cell_center_d({b.x * n_, b.y * n_, b.z * n_}); }
  // Centre of the block's first cell (local index 0); cell (lx,ly,lz) is at origin + l*resolution.
  Vec3f block_first_center(const BlockKey& b) const {
    return cell_center({b.x * n_, b.y * n_, b.z * n_});
  }
  // Box spanned by the centres of the block's cells: an observation farther than the support
  // radius from this box cannot touch any of its cells.
  Aabb block_center_box(const BlockKey& b) const {
    return {block_first_center(b), cell_center({b.x * n_ + n_ - 1, b.y * n_ + n_ - 1, b.z * n_ + n_ - 1})};
  }

 private:
  double resolution_;
  int n_;
};

}  // namespace bgkmap

template <>
struct std::hash<bgkmap::BlockKey> : bgkmap::BlockKeyHash {};
