#include "bench_support.hpp"

#include <benchmark/benchmark.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>

#include "bgkmap/integrate/cpu_integrator.hpp"
#include "bgkmap/integrate/opencl_integrator.hpp"
#include "bgkmap/io/pcd_io.hpp"
#include "datasets/locate.hpp"

namespace bgkmap::bench {

const std::vector<Scan>& sim_structured_scans() {
  static const std::vector<Scan> scans = [] {
    const std::filesystem::path dir = datasets::datasets_dir(BGKMAP_DEFAULT_DATASETS_DIR) / "sim_structured";
    std::vector<Scan> out;
    for (int i = 1; i <= 12; ++i) {
      char name[32];
      std::snprintf(name, sizeof name, "scan_%02d.pcd", i);
      if (!std::filesystem::exists(dir / name)) return std::vector<Scan>{};
      out.push_back(read_pcd(dir / name));
    }
    return out;
  }();
  return scans;
}

BuildParams sim_structured_params(int block_depth) {
  BuildParams p;
  p.grid.resolution_m = 0.1;
  p.grid.block_depth = block_depth;
  p.kernel.ell_m = 0.2f;
  p.kernel.sigma0 = 0.1f;
  p.preprocess.downsample_m = 0.1;
  p.preprocess.max_range_m = 8;
  return p;
}

namespace {

// Distance along the unit ray (o, d) to the scene, or INFINITY: the ground z = 0, walls x = +-60
// and y = +-45, and vertical pillars of radius 0.4 m on a 12 m grid.
double cast(const double o[3], const double d[3]) {
  double best = INFINITY;
  if (d[2] < 0) best = std::min(best, -o[2] / d[2]);
  for (int axis = 0; axis < 2; ++axis) {
    const double wall = axis == 0 ? 60.0 : 45.0;
    if (d[axis] > 0) best = std::min(best, (wall - o[axis]) / d[axis]);
    if (d[axis] < 0) best = std::min(best, (-wall - o[axis]) / d[axis]);
  }
  const double a = d[0] * d[0] + d[1] * d[1];
  if (a > 0) {
    for (int i = -5; i <= 5; ++i)
      for (int j = -4; j <= 4; ++j) {
        const double cx = i * 12.0 + 5.0, cy = j * 12.0 + 5.0, r = 0.4;
        const double ox = o[0] - cx, oy = o[1] - cy;
        const double b = ox * d[0] + oy * d[1];
        const double c = ox * ox + oy * oy - r * r;
        const double disc = b * b - a * c;
        if (disc < 0) continue;
        const double t = (-b - std::sqrt(disc)) / a;
        if (t > 0) best = std::min(best, t);
      }
  }
  return best;
}

}  // namespace

Scan synthetic_scan(const SyntheticLidar& lidar, int index) {
  Scan scan;
  scan.pose.position = {static_cast<float>(2.0 * index), 0.0f, 1.8f};
  scan.source = "synthetic-" + std::to_string(index);
  const double o[3] = {scan.pose.position.x, scan.pose.position.y, scan.pose.position.z};
  const int rings = lidar.rings, columns = lidar.columns;
  const double pi = 3.14159265358979323846;
  scan.points.reserve(static_cast<size_t>(rings) * columns);
  for (int r = 0; r < rings; ++r) {
    const double elevation = (-25.0 + 40.0 * r / std::max(rings - 1, 1)) * pi / 180.0;
    for (int c = 0; c < columns; ++c) {
      const double azimuth = 2 * pi * c / columns;
      const double d[3] = {std::cos(elevation) * std::cos(azimuth), std::cos(elevation) * std::sin(azimuth),
                           std::sin(elevation)};
      double t = cast(o, d);
      if (!std::isfinite(t)) t = 120.0;  // open sky: a return far beyond max range
      scan.points.push_back({static_cast<float>(o[0] + t * d[0]), static_cast<float>(o[1] + t * d[1]),
                             static_cast<float>(o[2] + t * d[2])});
    }
  }
  return scan;
}

Scan large_synthetic_scan(int index) { return synthetic_scan(SyntheticLidar{}, index); }

BuildParams synthetic_params(int block_depth, double max_range_m) {
  BuildParams p;
  p.grid.resolution_m = 0.1;
  p.grid.block_depth = block_depth;
  p.kernel.ell_m = 0.2f;
  p.kernel.sigma0 = 0.1f;
  p.preprocess.max_range_m = max_range_m;
  return p;
}

namespace {
// All cores (or OMP_NUM_THREADS), as the process starts. Not omp_get_max_threads() at the time of
// use: liboctomap's insertPointCloud (header code compiled into libbgkmap with OpenMP) calls
// omp_set_num_threads(1), after which a back end asked for "all cores" would get one thread.
const int kAllThreads = omp_get_max_threads();
}  // namespace

std::vector<ScanObservations> preprocess_scans(const std::vector<Scan>& scans, const BuildParams& params) {
  std::vector<ScanObservations> out(scans.size());
  PreprocessCounts counts;
  for (size_t i = 0; i < scans.size(); ++i) preprocess_scan(scans[i], params.preprocess, out[i], counts);
  return out;
}

std::unique_ptr<Integrator> make_backend(const std::string& name) {
  if (name == "cpu") return std::make_unique<CpuIntegrator>(kAllThreads);
  try {
    return make_opencl_integrator(OpenClOptions{}, 0);
  } catch (const OpenClUnavailable&) {
    return nullptr;
  }
}

namespace {
double clock_seconds(clockid_t clock) {
  timespec t{};
  clock_gettime(clock, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}
}  // namespace

CoresUsed::CoresUsed()
    : wall0_(clock_seconds(CLOCK_MONOTONIC)), cpu0_(clock_seconds(CLOCK_PROCESS_CPUTIME_ID)) {}

double CoresUsed::wall_seconds() const { return clock_seconds(CLOCK_MONOTONIC) - wall0_; }

double CoresUsed::cores() const {
  const double wall = wall_seconds();
  return wall > 0 ? (clock_seconds(CLOCK_PROCESS_CPUTIME_ID) - cpu0_) / wall : 0.0;
}

void add_backend_context() {
  benchmark::AddCustomContext("cpu_backend", make_backend("cpu")->info().device + ", " +
                                                 std::to_string(kAllThreads) + " OpenMP threads");
  const auto opencl = make_backend("opencl");
  benchmark::AddCustomContext("opencl_backend", opencl ? opencl->info().device : "unavailable");
}

int run_benchmarks(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  add_backend_context();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}

}  // namespace bgkmap::bench
