#include "integrate/local_frames.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace bgkmap {

LocalHit make_local_hit(const Vec3d& c0, const Vec3f& h) {
  return {static_cast<float>(h.x - c0.x), static_cast<float>(h.y - c0.y), static_cast<float>(h.z - c0.z)};
}

BeamLine beam_line(const Vec3f& origin, const Vec3f& free_end) {
  BeamLine line{{origin.x, origin.y, origin.z}, {0, 0, 0}, 0};
  const double v[3] = {double(free_end.x) - line.a[0], double(free_end.y) - line.a[1], double(free_end.z) - line.a[2]};
  line.length = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  if (line.length > 0)
    for (int i = 0; i < 3; ++i) line.u[i] = v[i] / line.length;
  return line;
}

LocalBeam local_beam(const Vec3d& c0, const Vec3d& mid, const BeamLine& line) {
  const double* a = line.a;
  const double* u = line.u;
  double s0 = 0;
  if (line.length > 0)
    s0 = std::clamp((mid.x - a[0]) * u[0] + (mid.y - a[1]) * u[1] + (mid.z - a[2]) * u[2], 0.0, line.length);
  LocalBeam b;
  b.qx = static_cast<float>(a[0] + s0 * u[0] - c0.x);
  b.qy = static_cast<float>(a[1] + s0 * u[1] - c0.y);
  b.qz = static_cast<float>(a[2] + s0 * u[2] - c0.z);
  b.ux = static_cast<float>(u[0]);
  b.uy = static_cast<float>(u[1]);
  b.uz = static_cast<float>(u[2]);
  b.s_min = static_cast<float>(-s0);
  b.s_max = static_cast<float>(line.length - s0);
  return b;
}

LocalBeam make_local_beam(const Vec3d& c0, const Vec3d& mid, const Vec3f& origin, const Vec3f& free_end) {
  return local_beam(c0, mid, beam_line(origin, free_end));
}

void write_local_frames(const Grid& grid, const ScanObservations& obs, ScanBuckets& out, std::vector<BeamLine>& lines,
                        int line_team, int pair_team) {
  out.hits.resize(out.hit_ids.size());
  out.beams.resize(out.beam_ids.size());
  lines.resize(obs.free_ends.size());
  const int64_t beam_count = static_cast<int64_t>(obs.free_ends.size());
#pragma omp parallel for num_threads(line_team) schedule(static)
  for (int64_t beam = 0; beam < beam_count; ++beam)
    lines[static_cast<size_t>(beam)] = beam_line(obs.origin, obs.free_ends[static_cast<size_t>(beam)]);
  const double mid_offset = 0.5 * (grid.cells_per_side() - 1) * grid.resolution();
  const int64_t block_count = static_cast<int64_t>(out.blocks.size());
#pragma omp parallel for num_threads(pair_team) schedule(dynamic, 16)
  for (int64_t b = 0; b < block_count; ++b) {
    const BlockWork& w = out.blocks[static_cast<size_t>(b)];
    const Vec3d c0 = grid.block_first_center_d(w.key);
    const Vec3d mid{c0.x + mid_offset, c0.y + mid_offset, c0.z + mid_offset};
    for (uint32_t k = w.hit_begin; k < w.hit_begin + w.hit_count; ++k)
      out.hits[k] = make_local_hit(c0, obs.hits[out.hit_ids[k]]);
    for (uint32_t k = w.beam_begin; k < w.beam_begin + w.beam_count; ++k)
      out.beams[k] = local_beam(c0, mid, lines[out.beam_ids[k]]);
  }
}

}  // namespace bgkmap
