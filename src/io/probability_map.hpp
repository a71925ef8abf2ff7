// The map of a method that keeps an occupancy probability per cell and no Beta posterior (gpom,
// wgpom, gpoctomap, bhm), written by extension: an OctoMap tree (probability_tree.hpp) or an
// export (map_export.hpp) of its cells, classified as a .bt is (above
// classify.occupied_threshold occupied, below classify.free_threshold free, else unknown) and
// without a variance (clouds leave the field out). Internal.
#pragma once

#include <filesystem>
#include <string>

#include "bgkmap/core/params.hpp"
#include "bgkmap/io/export_cells.hpp"
#include "io/probability_tree.hpp"

namespace bgkmap {

// Throws InputError naming the file for a .bgk (or an unknown extension): what `--method method`
// writes.
void require_probability_map_output(const std::filesystem::path& file, const std::string& method);

void write_probability_map(const std::filesystem::path& file, double resolution_m, const ClassifyParams& classify,
                           const CellProbabilities& cells, TreeValues ot_values);

// The cells as an export sees them; holds references to `classify` and `cells`.
ExportCells probability_export_cells(double resolution_m, const ClassifyParams& classify,
                                     const CellProbabilities& cells);

}  // namespace bgkmap
