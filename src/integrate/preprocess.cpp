#include <array>
#include <chrono>
#include <cmath>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/integrate/observations.hpp"
#include "core/stage_clock.hpp"

namespace bgkmap {

PreprocessCounts& PreprocessCounts::operator+=(const PreprocessCounts& o) {
  points_read += o.points_read;
  dropped_nonfinite += o.dropped_nonfinite;
  dropped_out_of_key_range += o.dropped_out_of_key_range;
  dropped_beyond_reach += o.dropped_beyond_reach;
  removed_by_downsampling += o.removed_by_downsampling;
  beyond_max_range += o.beyond_max_range;
  hits += o.hits;
  beams += o.beams;
  beams_shorter_than_margin += o.beams_shorter_than_margin;
  no_returns += o.no_returns;
  no_returns_dropped += o.no_returns_dropped;
  return *this;
}

namespace {
bool is_finite(const Vec3f& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z); }
}  // namespace

std::vector<Vec3f> usable_points(const Scan& scan, const PreprocessParams& params, PreprocessCounts& counts) {
  const Vec3f o = scan.pose.position;
  counts.points_read += scan.points.size();
  if (!is_finite(o)) {
    // Without an origin there are no beams; the scan's readers reject this, but stay safe.
    counts.dropped_nonfinite += scan.points.size();
    return {};
  }
  if (!within_key_range(o.x, o.y, o.z)) {
    counts.dropped_out_of_key_range += scan.points.size();
    return {};
  }

  std::vector<Vec3f> finite;
  finite.reserve(scan.points.size());
  const bool to_world = params.apply_viewpoint && !scan.points_in_world_frame;
  const double no_return = scan.no_return_range_m;
  for (const Vec3f& raw : scan.points) {
    Vec3f p = to_world ? scan.pose.transform(raw) : raw;
    if (!is_finite(p)) {
      ++counts.dropped_nonfinite;
      continue;
    }
    if (no_return > 0) {
      const double dx = p.x - o.x, dy = p.y - o.y, dz = p.z - o.z;
      const double range = std::sqrt(dx * dx + dy * dy + dz * dz);
      // The reader stores the reading in float; a relative 1e-6 absorbs that rounding.
      if (range >= no_return * (1 - 1e-6)) {
        ++counts.no_returns;
        if (params.max_range_m <= 0) {
          ++counts.no_returns_dropped;  // how much free space it saw is not known
          continue;
        }
        if (range <= params.max_range_m) {
          const double s = 2 * params.max_range_m / range;
          p = {static_cast<float>(o.x + dx * s), static_cast<float>(o.y + dy * s), static_cast<float>(o.z + dz * s)};
        }
      }
    }
    if (params.planar) p.z = static_cast<float>(params.plane_z_m);
    if (!within_key_range(p.x, p.y, p.z)) {
      ++counts.dropped_out_of_key_range;
      continue;
    }
    if (params.max_range_m <= 0) {
      const double dx = p.x - o.x, dy = p.y - o.y, dz = p.z - o.z;
      if (dx * dx + dy * dy + dz * dz > kReachWithoutMaxRangeM * kReachWithoutMaxRangeM) {
        ++counts.dropped_beyond_reach;
        continue;
      }
    }
    finite.push_back(p);
  }

  if (params.downsample_m > 0 && !finite.empty()) {
    std::vector<Vec3f> kept = voxel_downsample(finite, params.downsample_m);
    counts.removed_by_downsampling += finite.size() - kept.size();
    finite.swap(kept);
  }
  return finite;
}

PreparedScan prepare_scan(const Scan& scan, const PreprocessParams& params) {
  const Clock::time_point start = Clock::now();
  PreparedScan prepared;
  prepared.origin = scan.pose.position;
  if (params.planar) prepared.origin.z = static_cast<float>(params.plane_z_m);
  prepared.points = usable_points(scan, params, prepared.counts);
  if (scan.pose_covariance) {
    prepared.pose_covariance = scan.pose_covariance;
    prepared.pose_covariance_source = scan.pose_covariance_source;
  } else if (!params.pose_sigma.is_zero()) {
    prepared.pose_covariance = PoseCovariance::from_sigma(params.pose_sigma);
    prepared.pose_covariance_source = "--pose-sigma";
  }
  if (prepared.pose_covariance && prepared.pose_covariance->is_zero()) prepared.pose_covariance.reset();
  prepared.seconds = seconds_since(start);
  return prepared;
}

ReturnKind classify_return(double range_m, const PreprocessParams& params) {
  if (params.max_range_m > 0 && range_m > params.max_range_m)
    return params.beyond_range == BeyondRange::kDrop ? ReturnKind::kBeyondDropped : ReturnKind::kBeyondFree;
  return ReturnKind::kHit;
}

void observations_from(const PreparedScan& prepared, const PreprocessParams& params, ScanObservations& out,
                       PreprocessCounts& counts) {
  counts += prepared.counts;
  out.hits.clear();
  out.free_ends.clear();
  out.kernel_weight = 1.0f;
  const Vec3f o = prepared.origin;
  out.origin = o;
  out.hits.reserve(prepared.points.size());
  out.free_ends.reserve(prepared.points.size());
  for (const Vec3f& p : prepared.points) {
    const double dx = p.x - o.x, dy = p.y - o.y, dz = p.z - o.z;
    const double range = std::sqrt(dx * dx + dy * dy + dz * dz);
    const ReturnKind kind = classify_return(range, params);
    if (kind != ReturnKind::kHit) {
      ++counts.beyond_max_range;
      if (kind == ReturnKind::kBeyondDropped) continue;
      // OctoMap's convention: the beam saw free space up to max range, but no surface.
      const double s = params.max_range_m / range;
      out.free_ends.push_back({static_cast<float>(o.x + dx * s), static_cast<float>(o.y + dy * s),
                               static_cast<float>(o.z + dz * s)});
      continue;
    }
    out.hits.push_back(p);
    const double free_length = range - params.end_margin_m;
    if (free_length <= 0) {
      ++counts.beams_shorter_than_margin;
      continue;
    }
    const double s = free_length / range;
    out.free_ends.push_back({static_cast<float>(o.x + dx * s), static_cast<float>(o.y + dy * s),
                             static_cast<float>(o.z + dz * s)});
  }
  counts.hits += out.hits.size();
  counts.beams += out.free_ends.size();
}

void displace_observations(const ScanObservations& in, const PoseSigmaPoint& point, bool planar,
                           ScanObservations& out) {
  const std::array<double, 9> r = rotation_matrix(point.rotation);
  const Vec3f o = in.origin;
  const Vec3d t = point.translation;
  // p moved, in double; false (p dropped) where it leaves the key range, as preprocessing drops
  // points there, before it is rounded to float.
  const auto moved = [&](const Vec3f& p, Vec3f& q) {
    const double d[3] = {double(p.x) - o.x, double(p.y) - o.y, double(p.z) - o.z};
    const double x = o.x + t.x + r[0] * d[0] + r[1] * d[1] + r[2] * d[2];
    const double y = o.y + t.y + r[3] * d[0] + r[4] * d[1] + r[5] * d[2];
    const double z = planar ? double(o.z) : o.z + t.z + r[6] * d[0] + r[7] * d[1] + r[8] * d[2];
    if (!within_key_range(x, y, z)) return false;
    q = {static_cast<float>(x), static_cast<float>(y), static_cast<float>(z)};
    return true;
  };
  const auto move_all = [&](const std::vector<Vec3f>& from, std::vector<Vec3f>& to) {
    to.resize(from.size());
    size_t kept = 0;
    for (const Vec3f& p : from) kept += moved(p, to[kept]);
    to.resize(kept);
  };
  out.kernel_weight = static_cast<float>(in.kernel_weight * point.weight);
  if (!moved(o, out.origin)) {  // no beams without their origin
    out.origin = o;
    out.hits.clear();
    out.free_ends.clear();
    return;
  }
  move_all(in.hits, out.hits);
  move_all(in.free_ends, out.free_ends);
}

void preprocess_scan(const Scan& scan, const PreprocessParams& params, ScanObservations& out,
                     PreprocessCounts& counts) {
  observations_from(prepare_scan(scan, params), params, out, counts);
}

}  // namespace bgkmap
