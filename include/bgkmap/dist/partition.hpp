// The spatial partition of a distributed build: which process (rank) owns which block. Blocks
// are grouped in tiles of kTileBlocks^3 blocks; tiles are ordered along a Morton (Z-order) curve,
// so that a run of codes is a compact region of space, and the curve is cut into one run per
// rank of about equal estimated cost. Every key has an owner, including blocks no estimate saw.
#pragma once

#include <cstdint>
#include <unordered_map>
#include <utility>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/integrate/observations.hpp"

namespace bgkmap {

// Blocks per tile along each axis.
inline constexpr int32_t kTileBlocks = 4;

// The Morton code of the tile holding a block: 21 bits per axis (tile coordinates biased by
// 2^20 and clamped), x in the lowest bit of each triple.
uint64_t tile_code(const BlockKey& block);
// The same for tile coordinates (block coordinates floor-divided by kTileBlocks). Codes grow with
// each coordinate: every tile of a box has a code between those of its two corners.
uint64_t tile_code_of_tile(int32_t tx, int32_t ty, int32_t tz);

// Estimated integration cost per tile from scans' footprints: a hit adds 1 to its tile, a free
// segment 1 per block length along it (the blocks it passes are what it costs to integrate),
// sampled once per tile length.
class TileCosts {
 public:
  void add_scan(const Grid& grid, const ScanObservations& obs);
  void add(uint64_t code, double cost) { sums_[code] += cost; }
  // (code, cost) sorted by code, the costs of one code summed.
  std::vector<std::pair<uint64_t, double>> sorted() const;

 private:
  std::unordered_map<uint64_t, double> sums_;  // per tile code
};

class SpatialPartition {
 public:
  // One run of tile codes per rank, cut where the cumulative cost passes r / ranks of the total.
  // `costs`: (code, cost), sorted by code, codes unique. Ranks beyond the tiles own nothing.
  SpatialPartition(int ranks, const std::vector<std::pair<uint64_t, double>>& costs);
  // A partition given by its first codes (rank r owns codes in [first[r], first[r + 1])).
  explicit SpatialPartition(std::vector<uint64_t> first_codes);

  int ranks() const { return static_cast<int>(first_.size()); }
  int owner(const BlockKey& block) const { return owner_of_code(tile_code(block)); }
  int owner_of_code(uint64_t code) const;
  const std::vector<uint64_t>& first_codes() const { return first_; }
  // The estimated cost of each rank's run (empty for a partition given by codes).
  const std::vector<double>& estimated_costs() const { return cost_; }

 private:
  std::vector<uint64_t> first_;  // first_[0] = 0
  std::vector<double> cost_;
};

}  // namespace bgkmap
