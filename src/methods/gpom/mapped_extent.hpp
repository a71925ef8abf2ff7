// gpom's paper mode predicts everywhere in the mapped extent: the bounding box of every hit, beam
// end and sensor origin so far, grown by a margin. The blocks of it that no scan marked dirty
// hold the GP prior (no datum within reach of any of their cells), filled once, without a solve.
#pragma once

#include <cmath>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/integrate/observations.hpp"
#include "map/block_store.hpp"
#include "methods/gpom/cell_queries.hpp"
#include "methods/gpom/cell_solver.hpp"

namespace bgkmap::gpom {

class MappedExtent {
 public:
  void add(const ScanObservations& obs);
  bool empty() const { return !(lo_.x <= hi_.x); }

  // The keys of the blocks overlapping the box grown by margin_m (in 2-D those holding the plane).
  std::vector<BlockKey> blocks(const Grid& grid, const CellQueries& queries, double margin_m) const;

 private:
  Vec3d lo_{INFINITY, INFINITY, INFINITY}, hi_{-INFINITY, -INFINITY, -INFINITY};
};

// Every block of `keys` not yet in `cells` is added, each cell of it at solver.unreached (the prior).
void fill_unreached_blocks(const std::vector<BlockKey>& keys, const CellQueries& queries, const CellSolver& solver,
                           BlockStore<GpomCell>& cells);

}  // namespace bgkmap::gpom
