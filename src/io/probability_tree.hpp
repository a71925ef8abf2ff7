// A method's map written as an OctoMap tree from cells and their occupancy probabilities, for the
// methods that keep no Beta posterior (GP and Hilbert-map families), and the probabilities a tree
// of classified cells stores. Internal; free of OctoMap's headers, which stay in
// io/octomap_export.cpp.
#pragma once

#include <filesystem>
#include <functional>
#include <string>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/core/params.hpp"
#include "bgkmap/io/map_io.hpp"
#include "bgkmap/map/bgk_map.hpp"

namespace bgkmap {

// Hands every cell the map knows, with its P(occupied), to the visitor it is given.
using CellProbabilityVisitor = std::function<void(const CellIndex& cell, double probability)>;
using CellProbabilities = std::function<void(const CellProbabilityVisitor& visit)>;

// Throws InputError naming the file unless it is a tree (.ot or .bt): what `--method octomap` writes.
void require_tree_output(const std::filesystem::path& file, const std::string& method);

// Cells classified by state_of_probability (thresholds only: these methods' variances are not a
// Beta's). .bt: occupied and free cells; .ot: TreeValues (kClassified: those cells at
// classified_log_odds; kMean: every cell's probability as log-odds, clamped to [1e-6, 1 - 1e-6]
// and stored unchanged). Atomic. Throws std::runtime_error naming the file for a cell outside
// OctoMap's +-32768-cell range or a failed write; InputError for an extension other than .ot / .bt.
void write_probability_tree(const std::filesystem::path& file, double resolution_m, const ClassifyParams& classify,
                            const CellProbabilities& cells, TreeValues ot_values);

// The log-odds a classified .ot stores for an occupied or free cell of this probability: its
// log-odds (probability clamped to [1e-6, 1 - 1e-6]) where OctoMap's rule (occupied at log-odds
// >= 0) already gives `state`, which is always so for occupied_threshold >= 0.5 >= free_threshold.
// A threshold on the wrong side of 0.5 rescales its class linearly onto OctoMap's side, occupied
// (t, 1] onto (0.5, 1] and free [0, t) onto [0, 0.5), so the stored values keep the cells' order.
float classified_log_odds(double probability, CellState state, const ClassifyParams& classify);

}  // namespace bgkmap
