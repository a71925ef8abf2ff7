// Change detection between two maps of one grid (`bgkmap diff`): the cells one map classifies
// occupied and the other free. A cell either map calls unknown (no evidence, or a variance above
// the threshold) is no change: nothing was seen to change there.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/map/bgk_map.hpp"

namespace bgkmap {

struct CellChange {
  CellIndex index;
  double probability_a = 0, probability_b = 0;  // posterior means
};

struct MapChanges {
  double resolution_m = 0;
  std::vector<CellChange> cleared;   // occupied in A, free in B; sorted by (z, y, x)
  std::vector<CellChange> appeared;  // free in A, occupied in B; sorted likewise
  uint64_t compared = 0;             // cells with evidence in both maps
};

// Thresholds: each map's own, or these for both where given (ClassifyParams' meaning). Throws
// std::invalid_argument (one line) when the maps do not share a grid: another resolution, block
// size, or one planar and the other not, or planar in another layer.
MapChanges compare_maps(const BgkMap& a, const BgkMap& b, std::optional<float> occupied_threshold,
                        std::optional<float> free_threshold);

// Binary little-endian PLY, one point per changed cell at its centre: float x y z, float
// probability_a, probability_b, and int change (+1 appeared, -1 cleared).
void write_changes_ply(const std::filesystem::path& file, const MapChanges& changes);
// An OctoMap OcTree (.ot) of the changed cells only, each at B's probability: appeared cells
// read occupied and cleared cells free in OctoMap's tools.
void write_changes_ot(const std::filesystem::path& file, const MapChanges& changes);

}  // namespace bgkmap
