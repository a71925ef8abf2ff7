// `bgkmap simulate`: runs a simulation spec and writes, under the output folder,
//   scans/scan_NNNNN.pcd  world-frame points, VIEWPOINT = sensor pose (readable by `build`)
//   poses.txt             one line per scan, TUM format: time x y z qx qy qz qw (time = index / 10 Hz);
//                         with drift, the estimated poses followed by their covariance (pose_list.hpp)
//   poses_true.txt        with drift: the true poses
//   scene.yaml            the spec itself (the truth geometry, sensor, trajectory, seed)
//   truth.bt              the scene rasterized at spec.truth_resolution_m (when > 0), see truth.hpp;
//                         a dynamic scene as it is at the last scan (eval --truth-at: any other)
// Scans are streamed: one is in memory at a time. Every file is written atomically.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include "bgkmap/core/params.hpp"
#include "bgkmap/sim/scanner.hpp"
#include "bgkmap/sim/spec.hpp"
#include "bgkmap/sim/truth.hpp"

namespace bgkmap::sim {

struct SimulateOptions {
  std::filesystem::path output_dir;
  // Without it, an output folder whose scans/ already holds .pcd files is refused (a build of
  // the folder would mix both runs); with it those .pcd files are deleted first.
  bool overwrite = false;
  // Called after each scan with (scans done, scans in all).
  std::function<void(size_t, size_t)> on_scan;
  // Odometry drift (--drift): the standard deviations of each scan's increment of pose error
  // (pose_covariance.hpp's convention). The error of scan i is the sum of i + 1 independent
  // increments, so its covariance is (i + 1) Q, Q = diag of their squares. The scans are written
  // as seen from the estimated (drifted) poses, poses.txt holds those poses with that covariance,
  // poses_true.txt the true ones; the truth stays the true scene. Zero: no drift.
  PoseSigma drift;
};

struct SimulateReport {
  size_t scans = 0;
  ScanCounts counts;
  uint64_t scan_bytes = 0;  // size of the .pcd files
  std::optional<TruthStats> truth;
  double scan_seconds = 0, truth_seconds = 0;
};

SimulateReport simulate(const SimulationSpec& spec, const SimulateOptions& options);

// `bgkmap build --max-range R` reads these scans as intended for any R up to the sensor's max
// range: no-returns (stored beyond it) become free beams, returns beyond R too. Recommended: the
// sensor's max range, or the truth region's diagonal when shorter -- longer free beams would
// only clear space outside the region the truth covers, at a high cost (every beam of an open
// sky is a free segment of length R).
double recommended_max_range(const SimulationSpec& spec);
// "--max-range R" with R = recommended_max_range(spec).
std::string recommended_build_flags(const SimulationSpec& spec);

// "scan_00042.pcd": the name of scan `index` in a run of `count` scans (at least 5 digits).
std::string scan_file_name(size_t index, size_t count);

}  // namespace bgkmap::sim
