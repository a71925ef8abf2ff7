#include "launch_plan.hpp"

#include <algorithm>
#include <cstddef>
#include <cstring>

#include "integrate/beam_rows_8.hpp"

namespace bgkmap::opencl_detail {

void plan_launches(const ScanBuckets& buckets, const LaunchLimits& limits, std::vector<WorkPiece>& pieces,
                   std::vector<Launch>& launches) {
  pieces.clear();
  launches.clear();
  Launch current;
  auto close = [&] {
    if (current.piece_count > 0) launches.push_back(current);
    current = Launch{};
    current.first_piece = pieces.size();
  };
  for (uint32_t b = 0; b < buckets.blocks.size(); ++b) {
    const BlockWork& w = buckets.blocks[b];
    uint32_t hits_done = 0, beams_done = 0;
    do {
      if (current.piece_count == limits.max_jobs) close();
      const size_t hits = std::min<size_t>(w.hit_count - hits_done, limits.max_hits - current.hits);
      const size_t beams = std::min<size_t>(w.beam_count - beams_done, limits.max_beams - current.beams);
      const bool block_empty = w.hit_count == 0 && w.beam_count == 0;
      if (hits == 0 && beams == 0 && !block_empty) {
        close();  // this launch is full where the block still has work
        continue;
      }
      pieces.push_back({b, hits_done, static_cast<uint32_t>(hits), beams_done, static_cast<uint32_t>(beams)});
      ++current.piece_count;
      current.hits += hits;
      current.beams += beams;
      hits_done += static_cast<uint32_t>(hits);
      beams_done += static_cast<uint32_t>(beams);
    } while (hits_done < w.hit_count || beams_done < w.beam_count);
  }
  close();
}

void gather_launch(const ScanBuckets& buckets, const std::vector<WorkPiece>& pieces, const Launch& launch,
                   DeviceJob* jobs, LocalHit* hits, LocalBeam* beams, const RowReach8* row_reach,
                   uint64_t* beam_rows, int threads) {
  // Piece i's job (its offsets are the sums of the pieces before it) and its copies and row bits.
  auto gather_piece = [&](size_t i, uint32_t hit_at, uint32_t beam_at) {
    const WorkPiece& p = pieces[launch.first_piece + i];
    const BlockWork& w = buckets.blocks[p.block];
    jobs[i] = {w.slot, hit_at, p.hit_count, beam_at, p.beam_count};
    if (p.hit_count > 0)
      std::memcpy(hits + hit_at, buckets.hits.data() + w.hit_begin + p.hit_offset, p.hit_count * sizeof(LocalHit));
    if (p.beam_count > 0) {
      const LocalBeam* from = buckets.beams.data() + w.beam_begin + p.beam_offset;
      std::memcpy(beams + beam_at, from, p.beam_count * sizeof(LocalBeam));
      if (row_reach) beam_row_masks_8(*row_reach, from, p.beam_count, beam_rows + beam_at);
    }
  };
  uint32_t hit_at = 0, beam_at = 0;
  if (threads <= 1) {  // beside PoCL: one pass
    for (size_t i = 0; i < launch.piece_count; ++i) {
      const WorkPiece& p = pieces[launch.first_piece + i];
      gather_piece(i, hit_at, beam_at);
      hit_at += p.hit_count;
      beam_at += p.beam_count;
    }
    return;
  }
  // Several threads: the offsets first, then the pieces in parallel.
  for (size_t i = 0; i < launch.piece_count; ++i) {
    const WorkPiece& p = pieces[launch.first_piece + i];
    jobs[i].hit_begin = hit_at;
    jobs[i].beam_begin = beam_at;
    hit_at += p.hit_count;
    beam_at += p.beam_count;
  }
  const auto pieces_in_launch = static_cast<std::ptrdiff_t>(launch.piece_count);
#pragma omp parallel for num_threads(threads) schedule(dynamic, 64)
  for (std::ptrdiff_t i = 0; i < pieces_in_launch; ++i)
    gather_piece(static_cast<size_t>(i), jobs[i].hit_begin, jobs[i].beam_begin);
}

}  // namespace bgkmap::opencl_detail
