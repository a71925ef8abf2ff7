// gpom's cells and where they are queried: each cell's centre, in 2-D only the scans' plane's
// layer of cells, at the plane's height.
#pragma once

#include "bgkmap/core/grid.hpp"

namespace bgkmap::gpom {

// A cell's latent mean and variance (the mixture's, under pose hypotheses); unknown: no data within reach.
struct GpomCell {
  double mean = 0, variance = 0;
  bool known = false;
};

class CellQueries {
 public:
  explicit CellQueries(const Grid& grid) : grid_(grid) {}

  // The scans' dimension, once known: planar at height z, or 3-D.
  void set_plane(bool planar, double z) {
    planar_ = planar;
    plane_z_ = z;
    plane_cell_z_ = grid_.cell_of(0, 0, plane_z_).z;
  }
  bool planar() const { return planar_; }
  int cells_per_block() const { return grid_.cells_per_block(); }

  // In 2-D: whether the block holds the plane's layer of cells.
  bool block_holds_plane(const BlockKey& key) const {
    const int n = grid_.cells_per_side();
    return plane_cell_z_ >= key.z * n && plane_cell_z_ < (key.z + 1) * n;
  }

  Vec3d query_of(const CellIndex& c) const {
    Vec3d q = grid_.cell_center_d(c);
    if (planar_) q.z = plane_z_;
    return q;
  }

  // Calls visit(local, query) for every mapped cell of a block (only the plane's layer in 2-D),
  // `stride` cells apart (by index in the block).
  template <class Visit>
  void for_each_query(const BlockKey& key, int stride, Visit&& visit) const {
    const int n = grid_.cells_per_side();
    for (int local = 0; local < grid_.cells_per_block(); local += stride) {
      const CellIndex c = grid_.cell_at(key, local);
      if (planar_ && c.z != plane_cell_z_) {  // skip to the plane's layer: only it is mapped
        const int layer_start = (plane_cell_z_ - key.z * n) * n * n;
        if (local > layer_start) break;
        local = layer_start - stride;
        continue;
      }
      visit(local, query_of(c));
    }
  }

 private:
  Grid grid_;
  bool planar_ = false;
  double plane_z_ = 0;
  int32_t plane_cell_z_ = 0;
};

}  // namespace bgkmap::gpom
