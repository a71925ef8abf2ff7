// bucket_scan's working memory, kept between scans in ScanBuckets: a campus scan's millions of
// pairs in fresh vectors cost more in page faults than the grouping itself.
#pragma once

#include <vector>

#include "bgkmap/integrate/bucketing.hpp"
#include "integrate/bucket_parts.hpp"
#include "integrate/local_frames.hpp"

namespace bgkmap {

struct BucketScratch {
  std::vector<PartPairs> hits, beams;  // per part (bucket_scan cuts each kind into parts)
  std::vector<BeamLine> lines;         // per beam
  std::vector<BlockKey> keys;          // global block number -> key
  std::vector<uint32_t> table;
  std::vector<uint32_t> dense;
  std::vector<BlockWork> sorted;
  std::vector<uint32_t> order;
};

}  // namespace bgkmap
