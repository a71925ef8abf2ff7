// Which ranks of a distributed build each observation of a scan must reach: bucketing's own
// exact test, block by block, every observation of a block going to the block's owner. A rank
// that buckets what it receives then gives each of its blocks exactly the observations, in the
// same order, that bucketing the whole scan gives it (bucketing keeps a block's observations in
// input order, and the ids sent are in input order).
#pragma once

#include <cstdint>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/dist/partition.hpp"
#include "bgkmap/integrate/bucketing.hpp"
#include "bgkmap/integrate/observations.hpp"

namespace bgkmap {

class ObservationRouter {
 public:
  // Per rank, the ids of the hits and free ends (indices into obs) its blocks need, ascending.
  void route(const Grid& grid, float support_radius_m, const ScanObservations& obs, const SpatialPartition& partition,
             int threads, std::vector<std::vector<uint32_t>>& hits, std::vector<std::vector<uint32_t>>& ends);

 private:
  ScanBuckets buckets_;
  std::vector<std::vector<uint32_t>> by_owner_;
  std::vector<int> hit_mark_, end_mark_;
};

// The observations `hits` and `ends` name, in that order.
void select_observations(const ScanObservations& obs, const std::vector<uint32_t>& hits,
                         const std::vector<uint32_t>& ends, ScanObservations& out);

}  // namespace bgkmap
