// What a planner asks of a map beside a point's posterior: ray casts (the first occupied cell
// along a ray), the cells in an axis-aligned box, and the occupied cells. Cells are classified by
// the map's thresholds (CellPosterior::state with params().classify). Semantics: docs/QUERIES.md.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/map/bgk_map.hpp"

namespace bgkmap {

// What a ray does at an unknown cell: stop there (OctoMap's castRay by default), or pass through
// it (castRay's ignoreUnknown) and stop only at an occupied cell or the end of its range.
enum class UnknownPolicy { kStop = 0, kPass = 1 };
const char* to_string(UnknownPolicy policy);
// Throws std::invalid_argument naming the accepted values ("stop", "pass").
UnknownPolicy unknown_policy_from_string(const std::string& name);

// Why a ray cast ended.
enum class RayStop {
  kOccupied = 0,  // at an occupied cell: a hit
  kUnknown = 1,   // at an unknown cell (UnknownPolicy::kStop)
  kMaxRange = 2,  // the range ran out first; the cell is the one holding the range's end
  kMapEnd = 3,    // no range limit: the ray left the map's blocks, beyond which every cell is unknown
};
const char* to_string(RayStop stop);

// Where a ray cast ended: the cell, how far along the ray, and the cell's posterior and state.
struct RayCast {
  RayStop stop = RayStop::kMapEnd;
  CellIndex cell;
  Vec3d center;          // the cell's centre (a planar map's: on its plane)
  double distance = 0;   // metres along the ray to where it enters `cell` (0 for the start cell),
                         // or to the range's end (kMaxRange) or the map's edge (kMapEnd)
  CellPosterior posterior;
  CellState state = CellState::kUnknown;

  bool hit() const { return stop == RayStop::kOccupied; }
};

// Casts rays through one map, which must outlive it and not change meanwhile: the map's extent
// (the box of its blocks) is found once.
class RayCaster {
 public:
  explicit RayCaster(const BgkMap& map);

  // The first cell along origin + t * direction (t >= 0, direction of any non-zero length) that
  // ends the ray: an occupied cell, or with kStop an unknown one; the start cell counts. Cells are
  // walked by an exact 3-D DDA; a cell is reached when the ray enters it at t <= max_range
  // (0 or +inf: no limit). A planar map casts the ray in its layer's plane: origin's z and
  // direction's z are ignored and distances are in the plane. Throws std::invalid_argument for a
  // non-finite or zero direction (planar: no component in the plane), an origin beyond the key
  // range, a negative or NaN max_range, or a range whose end lies beyond the key range.
  RayCast cast(const Vec3d& origin, const Vec3d& direction, double max_range, UnknownPolicy policy) const;

 private:
  const BgkMap& map_;
  bool empty_ = true;
  Vec3d extent_min_, extent_max_;  // metres: the faces of the outermost blocks
};

// One ray; for many, make one RayCaster.
RayCast cast_ray(const BgkMap& map, const Vec3d& origin, const Vec3d& direction, double max_range,
                 UnknownPolicy policy);

// A closed axis-aligned box in metres: a cell is inside when its centre is (min <= c <= max, within
// 1e-9 of a cell: a bound written as a centre, 0.35 at 0.1 m, holds that centre).
struct CellBox {
  Vec3d min, max;
};
// Throws std::invalid_argument unless every bound is finite, within the key range and min <= max.
void check_cell_box(const CellBox& box);

struct MapCell {
  CellIndex index;
  Vec3d center;
  CellPosterior posterior;
  CellState state = CellState::kUnknown;
};

// Which cells a box query returns.
enum class CellSelection {
  kWithEvidence = 0,  // cells some observation changed (BgkMap::for_each_cell_with_evidence's)
  kAll = 1,           // every cell, those never observed at the prior (state unknown)
  kOccupied = 2,      // cells the map calls occupied
};

// Calls visit for the selected cells whose centres lie in `box` (nullptr: the whole map; kAll
// needs a box), block by block in key order (z, then y, then x) and in each block in its local
// order (x fastest). A planar map's box ignores z: its layer's cells under the box's (x, y).
// Throws std::invalid_argument for a bad box (check_cell_box) or kAll without one.
void for_each_cell_in_box(const BgkMap& map, const CellBox* box, CellSelection selection,
                          const std::function<void(const MapCell&)>& visit);
// How many cells centre in `box` (of a planar map: in its layer), observed or not: what
// CellSelection::kAll returns.
double cells_centred_in(const BgkMap& map, const CellBox& box);

std::vector<MapCell> cells_in_box(const BgkMap& map, const CellBox& box, bool include_unobserved = false);
// The occupied cells, of the whole map (box nullptr) or of a box.
std::vector<MapCell> occupied_cells(const BgkMap& map, const CellBox* box = nullptr);

}  // namespace bgkmap
