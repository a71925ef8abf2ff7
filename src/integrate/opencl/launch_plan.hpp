// Private to the OpenCL back end: how one scan's block work is cut into kernel launches that fit
// the device's buffers. Plain host code (no OpenCL), so it is tested on its own.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "bgkmap/integrate/bucketing.hpp"

namespace bgkmap {
struct RowReach8;  // integrate/beam_rows_8.hpp
}

namespace bgkmap::opencl_detail {

// One work-group's job as the kernels read it (core/bgk_layout.h).
using DeviceJob = ::BgkJob;

// What one launch may hold.
struct LaunchLimits {
  size_t max_jobs = 0, max_hits = 0, max_beams = 0;  // each at least 1
};

// A part of one block's work: a sub-range of its hits and of its beams. A block normally is one
// piece; only a block with more observations than a launch holds is cut into several.
struct WorkPiece {
  uint32_t block;  // index into ScanBuckets::blocks
  uint32_t hit_offset, hit_count;    // relative to the block's hit_begin
  uint32_t beam_offset, beam_count;  // relative to the block's beam_begin
};

struct Launch {
  size_t first_piece = 0, piece_count = 0;
  size_t hits = 0, beams = 0;  // totals of its pieces
};

// Cuts the blocks, in order, into pieces and launches within `limits`. Every hit and beam of
// every block lands in exactly one piece, the pieces of a block in order.
void plan_launches(const ScanBuckets& buckets, const LaunchLimits& limits, std::vector<WorkPiece>& pieces,
                   std::vector<Launch>& launches);

// Writes one launch's jobs and observations (contiguous, in piece order) into the given arrays,
// sized for launch.piece_count jobs, launch.hits hits and launch.beams beams. With `row_reach`
// (8^3 blocks, sparse kernel), also each beam's rows with cells it can reach (beam_rows_8.hpp: bit
// i for row i = z * 8 + y) into `beam_rows`, sized for launch.beams: computed here, vectorized,
// rather than by every work-group. The pieces are gathered on `threads` host threads (a GPU's
// host has its cores free for this; beside PoCL, one).
void gather_launch(const ScanBuckets& buckets, const std::vector<WorkPiece>& pieces, const Launch& launch,
                   DeviceJob* jobs, LocalHit* hits, LocalBeam* beams, const RowReach8* row_reach = nullptr,
                   uint64_t* beam_rows = nullptr, int threads = 1);

}  // namespace bgkmap::opencl_detail
