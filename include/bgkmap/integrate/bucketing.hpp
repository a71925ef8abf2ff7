// Host-side bucketing shared by every back end: which observations can touch which block.
//
// A hit goes to every block whose cell-centre box lies within the support radius of it; a beam's
// free segment to every block whose cell-centre box lies within the support radius of the
// segment (exact segment-box distance). The test is conservative at block level only: no
// observation within the support radius of any cell centre is ever missed.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "bgkmap/core/bgk_layout.h"
#include "bgkmap/core/grid.hpp"
#include "bgkmap/integrate/observations.hpp"

namespace bgkmap {

struct BucketScratch;

// A hit and a beam's free segment as one block sees them (core/bgk_layout.h: the same records
// on host and device); LocalBeam is computed in double on the host (src/integrate/local_frames.hpp).
using LocalHit = ::BgkLocalHit;
using LocalBeam = ::BgkLocalBeam;

// The observations one block must evaluate: ranges into ScanBuckets' per-pair arrays.
struct BlockWork {
  BlockKey key;
  uint32_t slot = 0;  // filled in by the mapper once the block exists in the map
  uint32_t hit_begin = 0, hit_count = 0;
  uint32_t beam_begin = 0, beam_count = 0;
};

struct ScanBuckets {
  std::vector<BlockWork> blocks;  // sorted by key
  std::vector<uint32_t> hit_ids;   // per (block, hit) pair: index into ScanObservations::hits
  std::vector<uint32_t> beam_ids;  // per (block, beam) pair: index into ScanObservations::free_ends
  std::vector<LocalHit> hits;      // per (block, hit) pair, parallel to hit_ids
  std::vector<LocalBeam> beams;    // per (block, beam) pair, parallel to beam_ids

  // bucket_scan's working memory, kept between scans (src/integrate/bucket_scratch.hpp); a copy
  // starts with none.
  class Scratch {
   public:
    Scratch();
    Scratch(const Scratch&);
    Scratch& operator=(const Scratch&);
    Scratch(Scratch&&) noexcept;
    Scratch& operator=(Scratch&&) noexcept;
    ~Scratch();
    BucketScratch& get();

   private:
    std::unique_ptr<BucketScratch> memory_;
  } scratch;

  void clear() {
    blocks.clear();
    hit_ids.clear();
    beam_ids.clear();
    hits.clear();
    beams.clear();
  }
};

// Buckets one scan's observations into blocks for the given support radius (metres), replacing
// what `out` held, on up to `threads` threads. The result does not depend on the thread count.
// A scan whose pairs would not fit the memory limit is refused, the message naming `reach_flag`
// (the flag that sets the radius for the method in use) among the remedies.
void bucket_scan(const Grid& grid, float support_radius_m, const ScanObservations& obs, ScanBuckets& out,
                 int threads = 1, const char* reach_flag = "--ell");

// A planar map's buckets: only the blocks holding its layer of cells (key.z == block_z) are kept,
// in their order.
void keep_layer_blocks(ScanBuckets& buckets, int32_t block_z);

}  // namespace bgkmap
