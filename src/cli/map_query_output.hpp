// bgkmap query's answers beside the points: ray casts read from a file of rays, the cells of a
// box and the occupied cells, one printed line each.
#pragma once

#include <string>
#include <string_view>

#include "bgkmap/map/map_queries.hpp"

namespace bgkmap::cli {

// "cx cy cz alpha beta mean variance state": the line of a cell, for points and boxes alike.
void print_cell_line(const Vec3d& center, const CellPosterior& posterior, CellState state);

// Casts the ray of every 'ox oy oz dx dy dz [max_range]' line of `rays_file` (- : standard input)
// and prints 'hit cx cy cz distance state stop'; a bad line is an InputError naming the file and line.
void print_ray_casts(const BgkMap& map, const std::string& rays_file, UnknownPolicy policy);

// print_cell_line for each selected cell centred in the box (nullptr: the whole map).
void print_cells_in_box(const BgkMap& map, const CellBox* box, CellSelection selection);

}  // namespace bgkmap::cli
