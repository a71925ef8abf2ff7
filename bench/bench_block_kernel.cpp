// Block kernel throughput of each back end's integrate() on the sim_structured scans, already
// preprocessed and bucketed (so only the block evaluation, and for OpenCL the transfers and the
// wait for the device, are timed), for several block depths.
//
// block_pairs_per_s counts every (cell, observation) pair of the touched blocks -- the work the
// bucketing defines, the same for every back end -- so it compares back ends. evaluated_per_s
// counts the pairs whose distance a back end actually computed after its own culling.
#include <benchmark/benchmark.h>

#include "bench_support.hpp"
#include "bgkmap/integrate/bucketing.hpp"
#include "bgkmap/map/bgk_map.hpp"

namespace bgkmap::bench {
namespace {

void BM_BlockKernel(benchmark::State& state, const std::string& backend) {
  const int depth = static_cast<int>(state.range(0));
  const std::vector<Scan>& scans = sim_structured_scans();
  if (scans.empty()) return state.SkipWithError("sim_structured missing (set BGKMAP_DATASETS)");
  std::unique_ptr<Integrator> integrator = make_backend(backend);
  if (!integrator) return state.SkipWithError("no OpenCL device");

  const BuildParams params = sim_structured_params(depth);
  BgkMap map(params);
  std::vector<ScanObservations> obs(scans.size());
  std::vector<ScanBuckets> buckets(scans.size());
  PreprocessCounts counts;
  for (size_t i = 0; i < scans.size(); ++i) {
    preprocess_scan(scans[i], params.preprocess, obs[i], counts);
    bucket_scan(map.grid(), params.kernel.support_radius_m(params.grid.resolution_m), obs[i], buckets[i]);
    for (BlockWork& w : buckets[i].blocks) w.slot = map.ensure_slot(w.key);
  }
  IntegrateStats warm_up;  // first launches compile the work-group functions on some drivers
  integrator->integrate(obs[0], buckets[0], map, warm_up);
  integrator->finish(warm_up);

  uint64_t block_pairs_per_pass = 0;
  for (const ScanBuckets& b : buckets)
    for (const BlockWork& w : b.blocks)
      block_pairs_per_pass += static_cast<uint64_t>(map.cells_per_block()) * (w.hit_count + w.beam_count);

  uint64_t evaluated = 0, passes = 0;
  for (auto _ : state) {
    IntegrateStats stats;
    for (size_t i = 0; i < scans.size(); ++i) integrator->integrate(obs[i], buckets[i], map, stats);
    integrator->finish(stats);
    evaluated += stats.pairs_evaluated;
    ++passes;
  }
  state.counters["block_pairs_per_s"] =
      benchmark::Counter(static_cast<double>(block_pairs_per_pass * passes), benchmark::Counter::kIsRate);
  state.counters["evaluated_per_s"] = benchmark::Counter(static_cast<double>(evaluated), benchmark::Counter::kIsRate);
  state.SetLabel(integrator->info().device);
}

BENCHMARK_CAPTURE(BM_BlockKernel, cpu, std::string("cpu"))
    ->Arg(3)
    ->Arg(4)
    ->Arg(5)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_BlockKernel, opencl, std::string("opencl"))
    ->Arg(3)
    ->Arg(4)
    ->Arg(5)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
}  // namespace bgkmap::bench

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  bgkmap::bench::add_backend_context();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
