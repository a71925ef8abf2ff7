// Which ranks of a distributed build each observation of a scan must reach. A rank buckets what
// it receives and keeps its own blocks; bucketing's test is per (observation, block) and keeps a
// block's observations in input order, so a block gets exactly the observations, in the same
// order, that bucketing the whole scan gives it as long as its owner receives every observation
// within reach of it, in input order: any superset is exact. The router sends each observation to
// the owners of the tiles that meet its reach box (a hit +- (l + one cell); a free segment, piece
// by piece of one tile length, each piece's box +- (l + one cell)), found from the Morton codes of
// the box's corners, splitting a box whose code range spans several owners. It costs O(1) per
// observation, against bucketing the whole scan; receivers get a few more observations than
// they need.
#pragma once

#include <cstdint>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/dist/partition.hpp"
#include "bgkmap/integrate/observations.hpp"

namespace bgkmap {

class ObservationRouter {
 public:
  // Per rank, the ids of the hits and free ends (indices into obs) its blocks need, ascending.
  // Per rank, the ids of the hits and free ends (indices into obs) to send it, ascending: every
  // observation within l of a block the rank owns, and some others.
  void route(const Grid& grid, float support_radius_m, const ScanObservations& obs, const SpatialPartition& partition,
             std::vector<std::vector<uint32_t>>& hits, std::vector<std::vector<uint32_t>>& ends);

 private:
  std::vector<int> owners_;  // of one observation, unsorted, maybe repeated
};

// The observations `hits` and `ends` name, in that order.
void select_observations(const ScanObservations& obs, const std::vector<uint32_t>& hits,
                         const std::vector<uint32_t>& ends, ScanObservations& out);

}  // namespace bgkmap
