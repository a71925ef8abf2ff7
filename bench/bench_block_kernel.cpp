// Block kernel throughput of each back end's integrate() on the sim_structured scans, already
// preprocessed and bucketed (so only the block evaluation, and for OpenCL the transfers and the
// wait for the device, are timed), for several block depths.
//
// block_pairs_per_s counts every (cell, observation) pair of the touched blocks -- the work the
// bucketing defines, the same for every back end -- so it compares back ends. evaluated_per_s
// counts the pairs whose distance a back end actually computed after its own culling, and
// within_l_share the share of those closer than l (the rest is wasted work).
//
// Against the roofline (bench/roofline_kernel.hpp: the CPU back end's per-pair math in an ideal
// layout, every pair within l), measured right after the timed loop of every run for the thread
// count the back end uses (the CPU back end's OpenMP threads; for OpenCL all cores, as PoCL's
// pthread device uses):
// - roofline_pairs_per_s: the roofline for this workload's mix, E / (E_hit / R_hit + E_beam / R_beam),
//   where E_hit and E_beam are the pairs the back end evaluates for the hits alone and the beams
//   alone (counted once beforehand by running it on the hits and on the beams separately) and
//   R_hit, R_beam the roofline's rates: beam pairs cost more than hit pairs;
// - roofline_fraction = evaluated_per_s / roofline_pairs_per_s: how close the block loops come
//   to the ideal per-pair speed;
// - useful_fraction = within_l_share * roofline_fraction: pairs within l per second against the
//   roofline, i.e. how close the whole block computation comes to evaluating only useful pairs
//   at the ideal speed.
// The roofline takes about 0.4 s after each run; cores_used and roofline_cores_used say whether
// either was short of cores (other processes on a shared machine).
#include <benchmark/benchmark.h>
#include <omp.h>


#include "bench_support.hpp"
#include "bgkmap/integrate/bucketing.hpp"
#include "bgkmap/map/bgk_map.hpp"
#include "roofline_kernel.hpp"

namespace bgkmap::bench {
namespace {

// The roofline for `threads` threads, measured right after the timed loop in every run (so in
// every repetition): on this shared VM the speed of the same code drifts by tens of percent over
// minutes, so a roofline measured once per process would not see the conditions the loop saw.
struct RooflineRates {
  RooflineMeasurement hit, beam;
};

RooflineRates measure_rooflines(int threads) {
  return {measure_roofline(PairKind::kHit, threads, 3, 0.05), measure_roofline(PairKind::kBeam, threads, 3, 0.05)};
}

// The buckets with only the hits (or only the beams) of every block; blocks left empty dropped.
ScanBuckets only(const ScanBuckets& buckets, PairKind kind) {
  ScanBuckets out = buckets;
  out.blocks.clear();
  for (BlockWork w : buckets.blocks) {
    (kind == PairKind::kHit ? w.beam_count : w.hit_count) = 0;
    if (w.hit_count + w.beam_count > 0) out.blocks.push_back(w);
  }
  return out;
}

// Pairs the back end evaluates for one kind of observation over all scans.
uint64_t evaluated_pairs_of(Integrator& integrator, const std::vector<ScanObservations>& obs,
                            const std::vector<ScanBuckets>& buckets, BgkMap& map, PairKind kind) {
  IntegrateStats stats;
  for (size_t i = 0; i < obs.size(); ++i) integrator.integrate(obs[i], only(buckets[i], kind), map, stats);
  integrator.finish(stats);
  return stats.pairs_evaluated;
}

void BM_BlockKernel(benchmark::State& state, const std::string& backend) {
  const int depth = static_cast<int>(state.range(0));
  const std::vector<Scan>& scans = sim_structured_scans();
  if (scans.empty()) return state.SkipWithError("sim_structured missing (set BGKMAP_DATASETS)");
  std::unique_ptr<Integrator> integrator = make_backend(backend);
  if (!integrator) return state.SkipWithError("no OpenCL device");

  const BuildParams params = sim_structured_params(depth);
  BgkMap map(params);
  const std::vector<ScanObservations> obs = preprocess_scans(scans, params);
  std::vector<ScanBuckets> buckets(scans.size());
  for (size_t i = 0; i < scans.size(); ++i) {
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
  const double hit_pairs = static_cast<double>(evaluated_pairs_of(*integrator, obs, buckets, map, PairKind::kHit));
  const double beam_pairs = static_cast<double>(evaluated_pairs_of(*integrator, obs, buckets, map, PairKind::kBeam));

  uint64_t evaluated = 0, within = 0, passes = 0;
  double kernel_seconds = 0;
  const CoresUsed usage;
  for (auto _ : state) {
    IntegrateStats stats;
    for (size_t i = 0; i < scans.size(); ++i) integrator->integrate(obs[i], buckets[i], map, stats);
    integrator->finish(stats);
    evaluated += stats.pairs_evaluated;
    within += stats.pairs_within_support;
    kernel_seconds += stats.device_kernel_s;
    ++passes;
  }
  const double seconds = usage.wall_seconds();
  const double cores_used = usage.cores();

  const int roofline_threads = backend == "cpu" ? integrator->info().threads : omp_get_max_threads();
  const RooflineRates roofline = measure_rooflines(roofline_threads);
  const double roofline_mix =
      (hit_pairs + beam_pairs) / (hit_pairs / roofline.hit.pairs_per_s + beam_pairs / roofline.beam.pairs_per_s);
  using benchmark::Counter;
  const double within_share = evaluated ? static_cast<double>(within) / static_cast<double>(evaluated) : 0.0;
  state.counters["block_pairs_per_s"] = Counter(static_cast<double>(block_pairs_per_pass * passes), Counter::kIsRate);
  state.counters["evaluated_per_s"] = Counter(static_cast<double>(evaluated), Counter::kIsRate);
  state.counters["within_l_share"] = within_share;
  state.counters["hit_pair_share"] = hit_pairs / (hit_pairs + beam_pairs);
  state.counters["roofline_pairs_per_s"] = roofline_mix;
  state.counters["roofline_hit_pairs_per_s"] = roofline.hit.pairs_per_s;
  state.counters["roofline_beam_pairs_per_s"] = roofline.beam.pairs_per_s;
  state.counters["roofline_threads"] = roofline_threads;
  // Cores the timed loop and the roofline measurement got (2 threads on a loaded machine: < 2).
  state.counters["cores_used"] = cores_used;
  state.counters["roofline_cores_used"] = 0.5 * (roofline.hit.cores_used + roofline.beam.cores_used);
  state.counters["roofline_fraction"] = static_cast<double>(evaluated) / seconds / roofline_mix;
  state.counters["useful_fraction"] = static_cast<double>(within) / seconds / roofline_mix;
  // OpenCL: the share of the wall time the device spent in the kernels (the rest: host work,
  // transfers, launches); 0 for the CPU path.
  state.counters["device_kernel_share"] = kernel_seconds / seconds;
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
  benchmark::AddCustomContext("cpu_clone", bgkmap::bench::cpu_clone_in_use());
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
