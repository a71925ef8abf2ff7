// Inputs and back ends shared by the benchmarks.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "bgkmap/core/params.hpp"
#include "bgkmap/core/scan.hpp"
#include "bgkmap/integrate/integrator.hpp"

namespace bgkmap::bench {

// The 12 sim_structured scans ($BGKMAP_DATASETS, else the build's default folder); empty when the
// folder is missing.
const std::vector<Scan>& sim_structured_scans();

// The paper's settings for sim_structured (la3dm): 0.1 m cells, l = 0.2 m, sigma0 = 0.1, max
// range 8 m, 0.1 m downsampling; blocks of 2^(depth-1) cells per side.
BuildParams sim_structured_params(int block_depth = 4);

// A large synthetic lidar scan: 64 rings of 1800 returns (115,200 points) over 360 degrees
// azimuth and -25..+15 degrees elevation, from a sensor 1.8 m above a ground plane among walls
// and pillars; returns beyond 50 m are free beams of 50 m. `index` moves the sensor 2 m along x.
Scan large_synthetic_scan(int index);
// Settings for it: 0.1 m cells, l = 0.2 m, max range 50 m, no downsampling.
BuildParams large_synthetic_params(int block_depth = 4);

// "cpu" (OpenMP, all cores) or "opencl" (the default device); null when OpenCL cannot run.
std::unique_ptr<Integrator> make_backend(const std::string& name);

// The benchmark context: each back end's device and threads.
void add_backend_context();

}  // namespace bgkmap::bench
