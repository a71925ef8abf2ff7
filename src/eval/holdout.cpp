#include "bgkmap/eval/holdout.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/io/scan_source.hpp"
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

size_t for_each_holdout_sample(const Scan& held_out, const PreprocessParams& params, double spacing,
                               const SampleVisitor& sample) {
  if (!(spacing > 0)) throw std::invalid_argument("the free-sample spacing must be positive");
  // The points as the build takes them, one per beam: no downsampling.
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
      sample(p.x, p.y, p.z, true);
    }
    for (int k = 1; k * spacing <= free_length + 1e-9; ++k) {  // counted, so no drift over long beams
      const double s = k * spacing / range;
      sample(o.x + dx * s, o.y + dy * s, o.z + dz * s, false);
    }
  }
  return used;
}

size_t add_holdout_samples(const Scan& held_out, const PreprocessParams& params, double spacing,
                           const PointScore& score, LabelledScores& out) {
  return for_each_holdout_sample(held_out, params, spacing, [&](double x, double y, double z, bool occupied) {
    (occupied ? out.positive : out.negative).push_back(score(x, y, z));
  });
}

std::vector<bool> split_scans(size_t scan_count, const ScanHoldoutParams& params) {
  if (!(params.fraction >= 0 && params.fraction <= 1)) throw std::invalid_argument("the held-out fraction must be in [0, 1]");
  if (params.run_length == 0) throw std::invalid_argument("the held-out run length must be at least 1 scan");
  const size_t runs = (scan_count + params.run_length - 1) / params.run_length;
  size_t held_runs = static_cast<size_t>(std::llround(params.fraction * double(runs)));
  if (params.fraction > 0 && runs > 0) held_runs = std::max<size_t>(held_runs, 1);
  // Runs ranked by their hash (ties, vanishingly rare, by index): the first held_runs are held out.
  std::vector<std::pair<uint64_t, size_t>> ranked(runs);
  for (size_t r = 0; r < runs; ++r) ranked[r] = {splitmix64(splitmix64(params.seed) ^ r), r};
  std::sort(ranked.begin(), ranked.end());
  std::vector<bool> held_out(scan_count, false);
  for (size_t k = 0; k < held_runs; ++k) {
    const size_t first = ranked[k].second * params.run_length;
    for (size_t i = first; i < std::min(scan_count, first + params.run_length); ++i) held_out[i] = true;
  }
  return held_out;
}

LabelledPoints holdout_points(const std::vector<Scan>& held_out, const PreprocessParams& params, double spacing) {
  LabelledPoints points;
  for (const Scan& scan : held_out)
    for_each_holdout_sample(scan, params, spacing, [&](double x, double y, double z, bool occupied) {
      (occupied ? points.occupied : points.free).push_back({x, y, z});
    });
  return points;
}

LabelledScores score_points(const LabelledPoints& points, const PointScore& score) {
  LabelledScores scores;
  scores.positive.reserve(points.occupied.size());
  scores.negative.reserve(points.free.size());
  for (const Vec3d& p : points.occupied) scores.positive.push_back(score(p.x, p.y, p.z));
  for (const Vec3d& p : points.free) scores.negative.push_back(score(p.x, p.y, p.z));
  return scores;
}

WholeScanSplit split_whole_scans(const std::vector<std::filesystem::path>& inputs, const ScanHoldoutParams& params) {
  std::vector<Scan> scans;
  {
    ScanSource source(inputs);
    for (Scan scan; source.next(scan); scan = Scan{}) scans.push_back(std::move(scan));
  }
  const std::vector<bool> held = split_scans(scans.size(), params);
  WholeScanSplit split;
  for (size_t i = 0; i < scans.size(); ++i) {
    if (held[i]) {
      split.held_out.push_back(std::move(scans[i]));
      split.held_out_indices.push_back(static_cast<uint32_t>(i));
    } else {
      split.training.push_back(std::move(scans[i]));
    }
  }
  return split;
}

}  // namespace bgkmap::eval
