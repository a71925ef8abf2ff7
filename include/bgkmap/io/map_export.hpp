// Maps out to a navigation stack, by extension: `.pgm` a ROS map_server occupancy grid with its
// `.yaml` beside it (occupancy_grid.hpp), `.ply` / `.pcd` the occupied cells as points with
// their probability and variance (cell_cloud.hpp). Read back by those tools, never by bgkmap.
#pragma once

#include <filesystem>

#include "bgkmap/io/export_cells.hpp"
#include "bgkmap/io/occupancy_grid.hpp"

namespace bgkmap {

// Writes `file` in the format its extension names, atomically (a .pgm and its .yaml one after
// the other, or together under an OutputBatch). `band` selects the heights a .pgm projects
// (occupancy_grid.hpp); clouds hold every occupied cell. Throws InputError naming the file for
// an extension that is not an export, an empty map or band, or a band on a planar map.
void write_map_export(const std::filesystem::path& file, const ExportCells& cells, const HeightBand& band = {});

}  // namespace bgkmap
