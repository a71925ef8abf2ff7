// The simulator's ray casting on the campus preset (2030 primitives, VLP-16 beams from poses on
// the loop): the BVH against testing every primitive, single-threaded, and whole simulated scans
// (OpenMP over beams, as `bgkmap simulate` runs them).
#include <benchmark/benchmark.h>

#include <cmath>

#include "bgkmap/sim/presets.hpp"
#include "bgkmap/sim/scanner.hpp"

namespace bgkmap::sim {
namespace {

struct Campus {
  SimulationSpec spec = make_preset("campus");
  Raycaster raycaster{spec.scene};
  std::vector<Vec3d> directions = beam_directions(spec.sensor);
  std::vector<Pose> poses = sample_poses(spec.trajectory);
};

const Campus& campus() {
  static const Campus c;
  return c;
}

// Rays of scan `k` (every 97th pose round the loop) in the world frame.
std::vector<Ray> scan_rays(const Campus& c, size_t k) {
  const Pose& p = c.poses[(k * 97) % c.poses.size()];
  const Vec3d o{p.position.x, p.position.y, p.position.z};
  const double yaw = 2 * std::atan2(p.qz, p.qw);
  std::vector<Ray> rays;
  for (const Vec3d& d : c.directions)
    rays.push_back({o, {std::cos(yaw) * d.x - std::sin(yaw) * d.y, std::sin(yaw) * d.x + std::cos(yaw) * d.y, d.z}});
  return rays;
}

void BM_CampusRaycast(benchmark::State& state, bool use_bvh) {
  const Campus& c = campus();
  const size_t stride = use_bvh ? 1 : 16;  // brute force: every 16th beam, or it takes minutes
  size_t k = 0, rays_cast = 0, hits = 0;
  for (auto _ : state) {
    const std::vector<Ray> rays = scan_rays(c, k++);
    for (size_t i = 0; i < rays.size(); i += stride) {
      const auto hit = use_bvh ? c.raycaster.cast(rays[i], c.spec.sensor.max_range_m)
                               : cast_brute_force(c.spec.scene, rays[i], c.spec.sensor.max_range_m);
      hits += hit.has_value();
      ++rays_cast;
    }
  }
  state.counters["rays_per_s"] = benchmark::Counter(static_cast<double>(rays_cast), benchmark::Counter::kIsRate);
  state.counters["hit_share"] = static_cast<double>(hits) / static_cast<double>(rays_cast);
  state.counters["bvh_nodes"] = static_cast<double>(c.raycaster.node_count());
}
BENCHMARK_CAPTURE(BM_CampusRaycast, bvh, true)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_CampusRaycast, brute_force, false)->Unit(benchmark::kMillisecond);

void BM_CampusSimulateScan(benchmark::State& state) {
  const Campus& c = campus();
  size_t k = 0;
  for (auto _ : state) {
    ScanCounts counts;
    const Scan scan = simulate_scan(c.raycaster, c.spec.sensor, c.directions, c.poses[(k * 97) % c.poses.size()],
                                    1, k, counts);
    benchmark::DoNotOptimize(scan.points.data());
    ++k;
  }
  state.counters["scans_per_s"] = benchmark::Counter(static_cast<double>(k), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_CampusSimulateScan)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace bgkmap::sim

BENCHMARK_MAIN();
