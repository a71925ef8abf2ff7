// The cells a map export is written from (ROS occupancy grids, clouds of occupied cells): every
// cell with evidence, its class, its probability and, where the method keeps one, its variance.
#pragma once

#include <functional>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/map/bgk_map.hpp"

namespace bgkmap {

struct ExportCell {
  CellIndex index;
  CellState state = CellState::kUnknown;
  double probability = 0;  // P(occupied): a BGK map's posterior mean
  double variance = 0;     // the posterior variance; 0 where ExportCells::has_variance is false
};

using ExportCellVisitor = std::function<void(const ExportCell& cell)>;

struct ExportCells {
  double resolution_m = 0;
  bool planar = false;        // a --2d map: one layer of cells
  bool has_variance = false;  // false for the methods that keep a probability only (gpom, bhm, ...)
  // Visits every cell with evidence; every other cell is unknown.
  std::function<void(const ExportCellVisitor& visit)> for_each;
};

// A BGK map's cells with evidence, classified by CellPosterior::state with the map's thresholds.
// Holds a reference to `map`, which must outlive the result.
ExportCells export_cells(const BgkMap& map);

}  // namespace bgkmap
