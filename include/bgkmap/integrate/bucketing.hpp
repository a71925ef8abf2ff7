// Host-side bucketing shared by every back end: which observations can touch which block.
//
// A hit goes to every block whose cell-centre box lies within the support radius of it; a beam's
// free segment to every block whose cell-centre box lies within the support radius of the
// segment (exact segment-box distance). The test is conservative at block level only: no
// observation within the support radius of any cell centre is ever missed.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "bgkmap/core/bgk_layout.h"
#include "bgkmap/core/grid.hpp"
#include "bgkmap/integrate/observations.hpp"

namespace bgkmap {

// A hit and a beam's free segment as one block sees them (core/bgk_layout.h: the same records
// on host and device); LocalBeam is computed in double on the host (make_local_beam).
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

  // bucket_scan's working memory, kept between scans: a campus scan's millions of pairs in fresh
  // vectors cost more in page faults than the grouping itself (issue #6: no per-scan reallocation).
  struct Scratch {
    // One part's pairs of one kind (hits or beams: a contiguous range of them), its blocks
    // numbered locally.
    struct PartPairs {
      std::vector<BlockKey> keys;                        // local block number -> key
      std::vector<uint32_t> table;                       // open-addressing index over keys
      std::vector<uint32_t> dense;                       // index over the keys in the scan's window
      std::vector<std::pair<uint32_t, uint32_t>> pairs;  // (local block number, observation)
      std::vector<uint32_t> to_global;                   // local -> global block number
      std::vector<uint32_t> cursor;                      // per global block: where the next pair goes
    };
    // A beam's free segment origin + s u, s in [0, length]: what every block of the beam shares.
    struct BeamLine {
      double a[3];  // origin
      double u[3];  // unit direction (0 for a zero-length segment)
      double length;
    };
    std::vector<PartPairs> hits, beams;    // per part (bucket_scan cuts each kind into parts)
    std::vector<BeamLine> lines;           // per beam
    std::vector<BlockKey> keys;            // global block number -> key
    std::vector<uint32_t> table;
    std::vector<uint32_t> dense;
    std::vector<BlockWork> sorted;
    std::vector<uint32_t> order;
  } scratch;

  void clear() {
    blocks.clear();
    hit_ids.clear();
    beam_ids.clear();
    hits.clear();
    beams.clear();
  }
};

// Squared distance from a point to a box (0 inside).
double point_box_dist2(const Vec3f& p, const Aabb& box);
// Exact squared distance between the segment a->b and a box (0 if they meet).
double segment_box_dist2(const Vec3f& a, const Vec3f& b, const Aabb& box);

// The block-local form of a hit and of a free segment (exposed for tests and other back ends).
LocalHit make_local_hit(const Vec3d& block_first_center, const Vec3f& hit);
LocalBeam make_local_beam(const Vec3d& block_first_center, const Vec3d& block_mid, const Vec3f& origin,
                          const Vec3f& free_end);

// Buckets one scan's observations into blocks for the given support radius (metres), replacing
// what `out` held, on up to `threads` threads. The result does not depend on the thread count.
void bucket_scan(const Grid& grid, float support_radius_m, const ScanObservations& obs, ScanBuckets& out,
                 int threads = 1);

// A planar map's buckets: only the blocks holding its layer of cells (key.z == block_z) are kept,
// in their order.
void keep_layer_blocks(ScanBuckets& buckets, int32_t block_z);

}  // namespace bgkmap
