// The occupied cells of a map as a point cloud (PLY or PCD, as PCL and CloudCompare read them):
// one point per occupied cell at its centre (x y z, float32, m) with the fields `probability`
// (P(occupied), a BGK map's posterior mean) and `variance` (float32; left out for the methods
// that keep no variance: gpom, wgpom, gpoctomap, bhm). Every height of a 3-D map.
#pragma once

#include <filesystem>

#include "bgkmap/io/export_cells.hpp"

namespace bgkmap {

// Binary little-endian PLY: element vertex with float properties x y z probability [variance].
void write_occupied_cells_ply(const std::filesystem::path& file, const ExportCells& cells);
// PCD v0.7, DATA binary: FIELDS x y z probability [variance], SIZE 4, TYPE F, HEIGHT 1.
void write_occupied_cells_pcd(const std::filesystem::path& file, const ExportCells& cells);

}  // namespace bgkmap
