// Observations in a block's frame (core/bgk_layout.h: the records both back ends read): a hit
// relative to the block's first cell centre, and a beam's free segment as its point nearest the
// block's middle plus a direction and the segment's extent either side, computed in double on
// the host so that far-from-origin maps lose no precision on the device.
#pragma once

#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/integrate/bucketing.hpp"

namespace bgkmap {

// A beam's free segment origin + s u, s in [0, length]: what every block of the beam shares,
// computed once per beam rather than once per (block, beam) pair.
struct BeamLine {
  double a[3];  // origin
  double u[3];  // unit direction (0 for a zero-length segment)
  double length;
};

BeamLine beam_line(const Vec3f& origin, const Vec3f& free_end);
LocalBeam local_beam(const Vec3d& block_first_center, const Vec3d& block_mid, const BeamLine& line);

LocalHit make_local_hit(const Vec3d& block_first_center, const Vec3f& hit);
LocalBeam make_local_beam(const Vec3d& block_first_center, const Vec3d& block_mid, const Vec3f& origin,
                          const Vec3f& free_end);

// Fills out.hits and out.beams (per pair, parallel to out.hit_ids and out.beam_ids) from the
// grouped ids: the beams' lines on `line_team` threads, the pairs on `pair_team`. `lines` is
// working memory.
void write_local_frames(const Grid& grid, const ScanObservations& obs, ScanBuckets& out, std::vector<BeamLine>& lines,
                        int line_team, int pair_team);

}  // namespace bgkmap
