// How a prepared scan becomes the observations and per-block buckets that the back ends
// evaluate: the one step in which the BGK methods differ. BGK-L's (the Mapper's default): the
// hits and one free segment per beam, bucketed by bucket_scan. BGKOctoMap's (--method bgk): free
// points sampled along each beam (src/methods/bgk/bgk_method.cpp).
#pragma once

#include <memory>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/integrate/bucketing.hpp"
#include "bgkmap/integrate/observations.hpp"

namespace bgkmap {

class ObservationStage {
 public:
  virtual ~ObservationStage() = default;

  // Preprocessing: the scan's observations into `out` (overwritten; its vectors keep their
  // capacity), counted in `counts` as observations_from does.
  virtual void observe(const PreparedScan& prepared, const PreprocessParams& params, ScanObservations& out,
                       PreprocessCounts& counts) = 0;
  // Bucketing: every (block, observation) pair within `support_radius_m` of a cell centre of the
  // block, as bucket_scan gives it.
  virtual void bucket(const Grid& grid, float support_radius_m, const ScanObservations& obs, ScanBuckets& out,
                      int threads) = 0;
};

// BGK-L's: observations_from and bucket_scan.
std::unique_ptr<ObservationStage> make_segment_observations();

}  // namespace bgkmap
