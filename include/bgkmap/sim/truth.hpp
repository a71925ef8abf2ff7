// The ground-truth occupancy of a scene on a grid: a cell is occupied when its centre lies inside
// a solid, free otherwise; only cells whose centre lies in the truth region are classified
// (the rest stay unknown). Cells are bgkmap's (index floor(x / resolution), docs/DESIGN.md),
// which are also OctoMap's cells at that resolution.
//
// Rather than visiting every cell (a 600 x 350 x 30 m campus has ~10^9 cells at 0.1 m), the
// region is split like an octree: a cube whose cell centres are all inside one solid, or all
// outside every solid, is emitted whole; only cubes straddling a surface are split further. The
// work and the output grow with the surface area, not the volume.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/sim/scene.hpp"

namespace bgkmap::sim {

// 2^level cells per side starting at cell `min` (aligned: min is a multiple of 2^level), all
// occupied or all free. Exactly OctoMap's node at depth 16 - level.
struct TruthCube {
  CellIndex min;
  int level = 0;
  bool occupied = false;
};

struct TruthStats {
  uint64_t occupied_cells = 0;
  uint64_t free_cells = 0;
  uint64_t cubes = 0;
};

// The octree's reach: cell indices in [-2^15, 2^15), as OctoMap's 16-level keys.
constexpr int kTruthLevels = 16;

// Throws std::invalid_argument when the cells of `region` do not fit the octree at `resolution`.
void check_truth_region(const Box3d& region, double resolution);

// Calls emit for disjoint cubes covering exactly the cells whose centre is in `region`; maximal
// ones (never eight siblings of one state, which would be their parent).
// Throws std::invalid_argument when the region does not fit the octree at this resolution.
TruthStats rasterize_truth(const Scene& scene, const Box3d& region, double resolution,
                           const std::function<void(const TruthCube&)>& emit);

// The same cells as an OctoMap OcTree written to a .bt file (atomically): occupied cells at the
// clamping maximum, free ones at the clamping minimum, uniform regions pruned into large nodes.
TruthStats write_truth_bt(const std::filesystem::path& file, const Scene& scene, const Box3d& region,
                          double resolution);

}  // namespace bgkmap::sim
