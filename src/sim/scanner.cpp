#include "bgkmap/sim/scanner.hpp"

#include <cmath>
#include <limits>

#include "core/splitmix.hpp"

namespace bgkmap::sim {

namespace {

Vec3f to_float(const Vec3d& v) { return {static_cast<float>(v.x), static_cast<float>(v.y), static_cast<float>(v.z)}; }
}  // namespace

Mat3 rotation_of(const Pose& pose) {
  double w = pose.qw, x = pose.qx, y = pose.qy, z = pose.qz;
  const double n = std::sqrt(w * w + x * x + y * y + z * z);
  w /= n, x /= n, y /= n, z /= n;
  Mat3 r;
  r.m[0][0] = 1 - 2 * (y * y + z * z), r.m[0][1] = 2 * (x * y - w * z), r.m[0][2] = 2 * (x * z + w * y);
  r.m[1][0] = 2 * (x * y + w * z), r.m[1][1] = 1 - 2 * (x * x + z * z), r.m[1][2] = 2 * (y * z - w * x);
  r.m[2][0] = 2 * (x * z - w * y), r.m[2][1] = 2 * (y * z + w * x), r.m[2][2] = 1 - 2 * (x * x + y * y);
  return r;
}

ScanCounts& ScanCounts::operator+=(const ScanCounts& o) {
  beams += o.beams;
  returns += o.returns;
  no_returns += o.no_returns;
  dropped += o.dropped;
  return *this;
}

double beam_uniform(uint64_t seed, uint64_t scan_index, uint64_t beam, uint32_t stream) {
  const uint64_t h = splitmix64(splitmix64(splitmix64(seed) ^ scan_index) ^ (beam * 4 + stream));
  return unit_interval(h);
}

Scan simulate_scan(const Raycaster& raycaster, const SensorModel& sensor, const std::vector<Vec3d>& directions,
                   const Pose& pose, uint64_t seed, uint64_t scan_index, ScanCounts& counts) {
  Scan scan;
  scan.pose = pose;
  scan.points.resize(directions.size());
  const Vec3d origin{pose.position.x, pose.position.y, pose.position.z};
  const Mat3 rotation = rotation_of(pose);
  const double max_range = sensor.max_range_m, sigma = sensor.range_noise_sigma_m, dropout = sensor.dropout;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const long n = static_cast<long>(directions.size());
  uint64_t returns = 0, dropped = 0;
#pragma omp parallel for schedule(dynamic, 256) reduction(+ : returns, dropped)
  for (long b = 0; b < n; ++b) {
    const Ray ray{origin, rotation * directions[b]};
    const auto hit = raycaster.cast(ray, max_range);
    if (!hit) {
      scan.points[b] = to_float(ray.at(kNoReturnRangeFactor * max_range));
      continue;
    }
    if (dropout > 0 && beam_uniform(seed, scan_index, b, 0) < dropout) {
      scan.points[b] = {nan, nan, nan};
      ++dropped;
      continue;
    }
    double range = hit->t;
    if (sigma > 0) {
      // Box-Muller; 1 - u keeps the logarithm's argument in (0, 1].
      const double u1 = 1.0 - beam_uniform(seed, scan_index, b, 1), u2 = beam_uniform(seed, scan_index, b, 2);
      range += sigma * std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
      range = std::fmin(std::fmax(range, 0.0), max_range);
    }
    scan.points[b] = to_float(ray.at(range));
    ++returns;
  }
  counts.beams += directions.size();
  counts.returns += returns;
  counts.dropped += dropped;
  counts.no_returns += directions.size() - returns - dropped;
  return scan;
}

}  // namespace bgkmap::sim
