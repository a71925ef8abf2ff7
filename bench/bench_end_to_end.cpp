// End to end insert time (preprocess, bucket, allocate, integrate, and for OpenCL the wait for
// the device) of each back end: the 12 sim_structured scans, and one large synthetic scan
// (115,200 points, 50 m range). The time reported is the Mapper's insert_s, the figure the build
// report gives (the final copy of the map back from the device is not in it).
#include <benchmark/benchmark.h>

#include "bench_support.hpp"
#include "bgkmap/mapper.hpp"

namespace bgkmap::bench {
namespace {

const std::vector<Scan>& large_synthetic_scans() {
  static const std::vector<Scan> scans = {large_synthetic_scan(0)};
  return scans;
}

void run_inserts(benchmark::State& state, const std::string& backend, const std::vector<Scan>& scans,
                 const BuildParams& params) {
  if (scans.empty()) return state.SkipWithError("sim_structured missing (set BGKMAP_DATASETS)");
  std::unique_ptr<Integrator> probe = make_backend(backend);
  if (!probe) return state.SkipWithError("no OpenCL device");
  {
    Mapper warm_up(params, std::move(probe));  // first launches compile work-group functions on PoCL
    warm_up.insert(scans[0]);
    warm_up.finish();
  }
  uint64_t points = 0;
  double compute_s = 0, bucket_s = 0;
  std::string device;
  for (auto _ : state) {
    Mapper mapper(params, make_backend(backend));
    for (const Scan& s : scans) mapper.insert(s);
    mapper.finish();
    state.SetIterationTime(mapper.timing().insert_s);
    compute_s += mapper.timing().compute_s;
    bucket_s += mapper.timing().bucket_s;
    points += mapper.counts().preprocess.points_read;
    device = mapper.backend().device;
  }
  state.counters["points_per_s"] = benchmark::Counter(static_cast<double>(points), benchmark::Counter::kIsRate);
  state.counters["bucket_s"] = benchmark::Counter(bucket_s, benchmark::Counter::kAvgIterations);
  state.counters["compute_s"] = benchmark::Counter(compute_s, benchmark::Counter::kAvgIterations);
  state.SetLabel(device);
}

void BM_SimStructured(benchmark::State& state, const std::string& backend) {
  run_inserts(state, backend, sim_structured_scans(), sim_structured_params(static_cast<int>(state.range(0))));
}

void BM_LargeSynthetic(benchmark::State& state, const std::string& backend) {
  run_inserts(state, backend, large_synthetic_scans(), synthetic_params(static_cast<int>(state.range(0))));
}

// Forgetting's cost: each iteration inserts the 12 scans without it, then with a half-life of 10
// scans (every block a scan touches was touched by an earlier scan, so each is decayed first);
// the time is the one with forgetting, `on_over_off` the ratio of the summed insert times.
void BM_SimStructuredForgetting(benchmark::State& state, const std::string& backend) {
  const std::vector<Scan>& scans = sim_structured_scans();
  if (scans.empty()) return state.SkipWithError("sim_structured missing (set BGKMAP_DATASETS)");
  if (!make_backend(backend)) return state.SkipWithError("no OpenCL device");
  const BuildParams params = sim_structured_params(static_cast<int>(state.range(0)));
  double off_s = 0, on_s = 0;
  for (auto _ : state) {
    for (const double half_life : {0.0, 10.0}) {
      Mapper mapper(params, make_backend(backend));
      mapper.set_forget_half_life(half_life);
      for (const Scan& s : scans) mapper.insert(s);
      mapper.finish();
      (half_life > 0 ? on_s : off_s) += mapper.timing().insert_s;
      if (half_life > 0) state.SetIterationTime(mapper.timing().insert_s);
    }
  }
  state.counters["off_s"] = benchmark::Counter(off_s, benchmark::Counter::kAvgIterations);
  state.counters["on_over_off"] = on_s / off_s;
}

BENCHMARK_CAPTURE(BM_SimStructured, cpu, std::string("cpu"))->Arg(4)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_SimStructured, opencl, std::string("opencl"))
    ->Arg(4)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_SimStructuredForgetting, cpu, std::string("cpu"))
    ->Arg(4)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_SimStructuredForgetting, opencl, std::string("opencl"))
    ->Arg(4)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_LargeSynthetic, cpu, std::string("cpu"))->Arg(4)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_LargeSynthetic, opencl, std::string("opencl"))
    ->Arg(4)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace bgkmap::bench

int main(int argc, char** argv) { return bgkmap::bench::run_benchmarks(argc, argv); }
