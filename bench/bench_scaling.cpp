// How insert time grows with points per scan and with max range: BGK-L through the Mapper on the
// CPU back end and on OpenCL, and liboctomap's insertPointCloud (--method octomap) for scale.
//
// Input: bench_support's synthetic lidar (ground, walls 45-60 m away, pillars), 32 rings with
// points / 32 returns each, so more points means denser azimuth over the same scene. Settings:
// 0.1 m cells, l = 0.2 m, no downsampling (synthetic_params).
// - BM_PointsPerScan: 1,024 .. 131,072 points per scan, max range 30 m;
// - BM_MaxRange: 16,384 points per scan, max range 5 .. 80 m.
// One iteration inserts two consecutive scans (the sensor moves 2 m) into a new map; the time is
// the method's insert_s (preprocess .. updated map, and for OpenCL the wait for the device) per
// scan. bench/plot_scaling turns the JSON output (--benchmark_out) into docs/img/bench_scaling.png.
#include <benchmark/benchmark.h>

#include <map>
#include <set>

#include "bench_support.hpp"
#include "bgkmap/methods/method.hpp"

namespace bgkmap::bench {
namespace {

constexpr int kRings = 32;
constexpr int kScansPerIteration = 2;
constexpr int kPointsForRangeSweep = 16384;
constexpr double kRangeForPointsSweep = 30;

// The scans of one point count, made once.
const std::vector<Scan>& lidar_scans(int points) {
  static std::map<int, std::vector<Scan>> made;
  std::vector<Scan>& scans = made[points];
  if (scans.empty())
    for (int i = 0; i < kScansPerIteration; ++i) scans.push_back(synthetic_scan({kRings, points / kRings}, i));
  return scans;
}

// "cpu" and "opencl": BGK-L on that back end (null when OpenCL cannot run); "octomap": liboctomap.
std::unique_ptr<MappingMethod> make_scaling_method(const std::string& name, const BuildParams& params) {
  if (name == "octomap") return make_method("octomap", params, MethodParams{}, BackendOptions{});
  std::unique_ptr<Integrator> integrator = make_backend(name);
  if (!integrator) return nullptr;
  return make_bgkl_method(std::make_unique<Mapper>(params, std::move(integrator)));
}

void run_inserts(benchmark::State& state, const std::string& method, int points, const BuildParams& params) {
  const std::vector<Scan>& scans = lidar_scans(points);
  static std::set<std::string> warmed_up;
  if (!warmed_up.count(method)) {
    // First launches compile the work-group functions on PoCL (cached for the process after
    // that): not part of the timing.
    std::unique_ptr<MappingMethod> warm_up = make_scaling_method(method, params);
    if (!warm_up) return state.SkipWithError("no OpenCL device");
    warm_up->insert(lidar_scans(1024).front());
    warm_up->finish();
    warmed_up.insert(method);
  }
  uint64_t points_read = 0, pairs = 0, within = 0, blocks = 0;
  double insert_s = 0, preprocess_s = 0, bucket_s = 0, update_s = 0, compute_s = 0;
  std::string device;
  const CoresUsed usage;
  for (auto _ : state) {
    std::unique_ptr<MappingMethod> m = make_scaling_method(method, params);
    for (const Scan& s : scans) m->insert(s);
    m->finish();
    state.SetIterationTime(m->timing().insert_s / kScansPerIteration);
    points_read += m->counts().preprocess.points_read;
    pairs += m->counts().integrate.pairs_evaluated;
    within += m->counts().integrate.pairs_within_support;
    const InsertTiming& t = m->timing();
    insert_s += t.insert_s;
    preprocess_s += t.preprocess_s;
    bucket_s += t.bucket_s;
    update_s += t.update_s;
    compute_s += t.compute_s;
    blocks += m->counts().block_visits;
    device = m->backend().device;
  }
  const double scans_done = static_cast<double>(state.iterations()) * kScansPerIteration;
  state.counters["cores_used"] = usage.cores();
  state.counters["points_per_scan"] = static_cast<double>(points_read) / scans_done;
  state.counters["max_range_m"] = params.preprocess.max_range_m;
  state.counters["points_per_s"] = static_cast<double>(points_read) / insert_s;
  // The stages of insert_s per scan (bucket_s and update_s are 0 for octomap, whose ray casting
  // is all compute_s), and the blocks each scan touches.
  state.counters["preprocess_s"] = preprocess_s / scans_done;
  state.counters["bucket_s"] = bucket_s / scans_done;
  state.counters["update_s"] = update_s / scans_done;
  state.counters["compute_s"] = compute_s / scans_done;
  if (pairs > 0) {
    state.counters["blocks_per_scan"] = static_cast<double>(blocks) / scans_done;
    state.counters["pairs_per_scan"] = static_cast<double>(pairs) / scans_done;
    state.counters["within_l_share"] = static_cast<double>(within) / static_cast<double>(pairs);
  }
  state.SetLabel(device);
}

void BM_PointsPerScan(benchmark::State& state, const std::string& method) {
  run_inserts(state, method, static_cast<int>(state.range(0)), synthetic_params(4, kRangeForPointsSweep));
}

void BM_MaxRange(benchmark::State& state, const std::string& method) {
  run_inserts(state, method, kPointsForRangeSweep, synthetic_params(4, static_cast<double>(state.range(0))));
}

void points_sweep(benchmark::internal::Benchmark* b) {
  b->ArgName("points")->RangeMultiplier(2)->Range(1 << 10, 1 << 17)->UseManualTime()->Unit(benchmark::kMillisecond);
}

void range_sweep(benchmark::internal::Benchmark* b) {
  b->ArgName("range_m");
  for (int r : {5, 10, 20, 40, 80}) b->Arg(r);
  b->UseManualTime()->Unit(benchmark::kMillisecond);
}

BENCHMARK_CAPTURE(BM_PointsPerScan, cpu, std::string("cpu"))->Apply(points_sweep);
BENCHMARK_CAPTURE(BM_PointsPerScan, opencl, std::string("opencl"))->Apply(points_sweep);
BENCHMARK_CAPTURE(BM_PointsPerScan, octomap, std::string("octomap"))->Apply(points_sweep);
BENCHMARK_CAPTURE(BM_MaxRange, cpu, std::string("cpu"))->Apply(range_sweep);
BENCHMARK_CAPTURE(BM_MaxRange, opencl, std::string("opencl"))->Apply(range_sweep);
BENCHMARK_CAPTURE(BM_MaxRange, octomap, std::string("octomap"))->Apply(range_sweep);

}  // namespace
}  // namespace bgkmap::bench

int main(int argc, char** argv) { return bgkmap::bench::run_benchmarks(argc, argv); }
