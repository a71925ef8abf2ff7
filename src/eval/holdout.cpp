#include "bgkmap/eval/holdout.hpp"

#include <cmath>
#include <stdexcept>

#include "bgkmap/integrate/observations.hpp"
#include "core/splitmix.hpp"

namespace bgkmap::eval {

namespace {

double beam_uniform(uint64_t seed, uint64_t scan_index, uint64_t beam) {
  const uint64_t h = splitmix64(splitmix64(splitmix64(seed) ^ scan_index) ^ beam);
  return unit_interval(h);
}

}  // namespace

BeamSplit split_beams(size_t beam_count, double fraction, uint64_t seed, uint64_t scan_index) {
  if (!(fraction >= 0 && fraction <= 1)) throw std::invalid_argument("the held-out fraction must be in [0, 1]");
  BeamSplit split;
  for (size_t i = 0; i < beam_count; ++i)
    (beam_uniform(seed, scan_index, i) < fraction ? split.held_out : split.kept).push_back(static_cast<uint32_t>(i));
  return split;
}

Scan select_beams(const Scan& scan, const std::vector<uint32_t>& indices) {
  Scan out;
  out.pose = scan.pose;
  out.source = scan.source;
  out.points_in_world_frame = scan.points_in_world_frame;
  out.points.reserve(indices.size());
  for (uint32_t i : indices) out.points.push_back(scan.points.at(i));
  return out;
}

size_t add_holdout_samples(const Scan& held_out, const PreprocessParams& params, double spacing,
                           const PointScore& score, LabelledScores& out) {
  if (!(spacing > 0)) throw std::invalid_argument("the free-sample spacing must be positive");
  // The points as the build takes them (world frame, NaN/Inf and no-return readings handled),
  // one per beam: no downsampling.
  PreprocessParams per_beam = params;
  per_beam.downsample_m = 0;
  PreprocessCounts ignored;
  const std::vector<Vec3f> points = usable_points(held_out, per_beam, ignored);
  const Vec3f o = held_out.pose.position;
  size_t used = 0;
  for (const Vec3f& p : points) {
    const double dx = p.x - o.x, dy = p.y - o.y, dz = p.z - o.z;
    const double range = std::sqrt(dx * dx + dy * dy + dz * dz);
    if (range <= 0) continue;
    const ReturnKind kind = classify_return(range, params);
    if (kind == ReturnKind::kBeyondDropped) continue;  // as the maps were built
    const bool beyond = kind == ReturnKind::kBeyondFree;
    ++used;
    double free_length = range - spacing;
    if (beyond) {
      free_length = params.max_range_m - spacing;  // no return within max range: free space only
    } else {
      out.positive.push_back(score(p.x, p.y, p.z));
    }
    for (int k = 1; k * spacing <= free_length + 1e-9; ++k) {  // counted, so no drift over long beams
      const double s = k * spacing / range;
      out.negative.push_back(score(o.x + dx * s, o.y + dy * s, o.z + dz * s));
    }
  }
  return used;
}

}  // namespace bgkmap::eval
