// bucket_scan alone (include/bgkmap/integrate/bucketing.hpp): which observations go to which
// block, on scans preprocessed beforehand, with 1 and 2 threads (the threads bucket the beams).
// Inputs: the 12 sim_structured scans (la3dm's settings) and the large synthetic scan (115,200
// points, 50 m range). One iteration buckets every scan of the input into one reused ScanBuckets,
// as the Mapper does.
//
// pairs_per_s: (block, observation) pairs written per second (hits and beams); beams_per_s: the
// scans' free beams bucketed per second (one per point within or beyond max range).
#include <benchmark/benchmark.h>

#include "bench_support.hpp"
#include "bgkmap/integrate/bucketing.hpp"
#include "bgkmap/map/bgk_map.hpp"

namespace bgkmap::bench {
namespace {

void run_bucketing(benchmark::State& state, const std::vector<Scan>& scans, const BuildParams& params) {
  if (scans.empty()) return state.SkipWithError("sim_structured missing (set BGKMAP_DATASETS)");
  const int threads = static_cast<int>(state.range(0));
  const BgkMap map(params);
  const float radius = params.kernel.support_radius_m(params.grid.resolution_m);
  const std::vector<ScanObservations> obs = preprocess_scans(scans, params);
  ScanBuckets buckets;
  bucket_scan(map.grid(), radius, obs[0], buckets, threads);  // grow the buffers once, as after the first scan

  uint64_t pairs = 0, beams = 0, blocks = 0;
  const CoresUsed usage;
  for (auto _ : state) {
    for (const ScanObservations& o : obs) {
      bucket_scan(map.grid(), radius, o, buckets, threads);
      pairs += buckets.hit_ids.size() + buckets.beam_ids.size();
      beams += o.free_ends.size();
      blocks += buckets.blocks.size();
    }
  }
  using benchmark::Counter;
  state.counters["pairs_per_s"] = Counter(static_cast<double>(pairs), Counter::kIsRate);
  state.counters["beams_per_s"] = Counter(static_cast<double>(beams), Counter::kIsRate);
  state.counters["blocks_per_pass"] = Counter(static_cast<double>(blocks), Counter::kAvgIterations);
  state.counters["cores_used"] = usage.cores();
  state.counters["pairs_per_pass"] = Counter(static_cast<double>(pairs), Counter::kAvgIterations);
}

void BM_BucketSimStructured(benchmark::State& state) {
  run_bucketing(state, sim_structured_scans(), sim_structured_params());
}

void BM_BucketLargeSynthetic(benchmark::State& state) {
  static const std::vector<Scan> scans = {large_synthetic_scan(0)};
  run_bucketing(state, scans, synthetic_params());
}

BENCHMARK(BM_BucketSimStructured)->ArgName("threads")->Arg(1)->Arg(2)->UseRealTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BucketLargeSynthetic)->ArgName("threads")->Arg(1)->Arg(2)->UseRealTime()->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace bgkmap::bench

BENCHMARK_MAIN();
