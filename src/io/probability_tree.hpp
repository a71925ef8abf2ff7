// A method's map written as an OctoMap tree from cells and their occupancy probabilities, for the
// methods that keep no Beta posterior (GP and Hilbert-map families). Internal; free of OctoMap's
// headers, which stay in io/octomap_export.cpp.
#pragma once

#include <filesystem>
#include <functional>
#include <string>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/core/params.hpp"

namespace bgkmap {

// Hands every cell the map knows, with its P(occupied), to the visitor it is given.
using CellProbabilityVisitor = std::function<void(const CellIndex& cell, double probability)>;
using CellProbabilities = std::function<void(const CellProbabilityVisitor& visit)>;

// .ot: each cell's probability as log-odds, clamped to [1e-6, 1 - 1e-6] and stored unchanged (the
// tree's clamping set to the same bounds, as for the BGK maps); .bt: cells above
// classify.occupied_threshold occupied, below classify.free_threshold free, the rest left out.
// Atomic. Throws std::runtime_error naming the file for a cell outside OctoMap's +-32768-cell
// range or a failed write; InputError for an extension other than .ot / .bt.
// Throws InputError naming the file unless it is a tree (.ot or .bt): what `--method method`
// writes when it keeps no Beta posterior.
void require_tree_output(const std::filesystem::path& file, const std::string& method);

void write_probability_tree(const std::filesystem::path& file, double resolution_m, const ClassifyParams& classify,
                            const CellProbabilities& cells);

}  // namespace bgkmap
