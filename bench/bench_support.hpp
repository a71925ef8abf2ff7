// Inputs and back ends shared by the benchmarks.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "bgkmap/core/params.hpp"
#include "bgkmap/core/scan.hpp"
#include "bgkmap/integrate/integrator.hpp"
#include "bgkmap/integrate/observations.hpp"

namespace bgkmap::bench {

// The 12 sim_structured scans ($BGKMAP_DATASETS, else the build's default folder); empty when the
// folder is missing.
const std::vector<Scan>& sim_structured_scans();

// The paper's settings for sim_structured (la3dm): 0.1 m cells, l = 0.2 m, sigma0 = 0.1, max
// range 8 m, 0.1 m downsampling; blocks of 2^(depth-1) cells per side.
BuildParams sim_structured_params(int block_depth = 4);

// A synthetic lidar: `rings` rings of `columns` returns each over 360 degrees azimuth and
// -25..+15 degrees elevation, from a sensor 1.8 m above a ground plane among walls 45-60 m away
// and pillars on a 12 m grid (open sky: a return 120 m away). `index` moves the sensor 2 m along x.
struct SyntheticLidar {
  int rings = 64;
  int columns = 1800;
};
Scan synthetic_scan(const SyntheticLidar& lidar, int index);
// The large one: 64 rings of 1800 returns (115,200 points).
Scan large_synthetic_scan(int index);
// Settings for synthetic scans: 0.1 m cells, l = 0.2 m, no downsampling; returns beyond
// max_range_m are free beams of that length.
BuildParams synthetic_params(int block_depth = 4, double max_range_m = 50);

// Each scan preprocessed with params.preprocess (the observations a back end integrates).
std::vector<ScanObservations> preprocess_scans(const std::vector<Scan>& scans, const BuildParams& params);

// "cpu" (OpenMP, all cores) or "opencl" (the default device); null when OpenCL cannot run.
std::unique_ptr<Integrator> make_backend(const std::string& name);

// Wall seconds and the CPU seconds of the whole process (every thread, PoCL's included) since
// construction. Their ratio, reported as the counter cores_used, says whether a benchmark got the
// cores it asked for: on a shared machine a run with 2 threads that saw 1.2 cores was slowed by
// other processes, whatever its time says. (Spin-waiting OpenMP threads count as busy.)
class CoresUsed {
 public:
  CoresUsed();
  double wall_seconds() const;
  double cores() const;  // process CPU seconds / wall seconds

 private:
  double wall0_, cpu0_;
};

// The benchmark context: each back end's device and threads.
void add_backend_context();

// main() of the benchmarks that compare back ends: Google Benchmark with the back-end context.
int run_benchmarks(int argc, char** argv);

}  // namespace bgkmap::bench
