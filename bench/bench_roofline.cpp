// This machine's pair-evaluation roofline (bench/roofline_kernel.hpp says what it is and what it
// is not): the CPU back end's per-pair math for hits and for beams in the ideal layout, every
// pair within l, with one thread and with all threads. One iteration is one pass of 4096
// observations against a 1024-cell tile on every thread.
//
// pairs_per_s is the figure bench_block_kernel's evaluated_per_s is compared with
// (bench_block_kernel measures the same roofline right after each of its runs, because this
// VM's speed drifts by 10-20 % between runs: roofline_fraction there); within_l_share is 1 by
// construction and is reported so that this stays checked; cores_used < threads means other
// processes took cores.
#include <benchmark/benchmark.h>
#include <omp.h>

#include "bench_support.hpp"
#include "roofline_kernel.hpp"

namespace bgkmap::bench {
namespace {

void BM_Roofline(benchmark::State& state, PairKind kind) {
  Roofline roofline(kind, static_cast<int>(state.range(0)));
  roofline.pass();  // warm the tile and the threads
  uint64_t pairs = 0, within = 0;
  const CoresUsed usage;
  for (auto _ : state) {
    const RooflinePass p = roofline.pass();
    pairs += p.pairs;
    within += p.within;
  }
  state.counters["pairs_per_s"] = benchmark::Counter(static_cast<double>(pairs), benchmark::Counter::kIsRate);
  state.counters["within_l_share"] = pairs ? static_cast<double>(within) / static_cast<double>(pairs) : 0.0;
  state.counters["threads"] = roofline.threads();
  state.counters["cores_used"] = usage.cores();
}

void thread_counts(benchmark::internal::Benchmark* b) {
  b->Arg(1);
  if (omp_get_max_threads() > 1) b->Arg(omp_get_max_threads());
  b->ArgName("threads")->UseRealTime()->Unit(benchmark::kMillisecond);
}

BENCHMARK_CAPTURE(BM_Roofline, hit, PairKind::kHit)->Apply(thread_counts);
BENCHMARK_CAPTURE(BM_Roofline, beam, PairKind::kBeam)->Apply(thread_counts);

}  // namespace
}  // namespace bgkmap::bench

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::AddCustomContext("cpu_clone", bgkmap::bench::cpu_clone_in_use());
  benchmark::AddCustomContext("omp_max_threads", std::to_string(omp_get_max_threads()));
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
