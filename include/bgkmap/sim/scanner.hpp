// One simulated scan: every beam of a sensor cast from a pose into a scene, with range noise and
// dropout drawn from a counter-based generator, so a (seed, scan, beam) triple always gives the
// same number whatever the thread count.
//
// How beams are stored (the points are world-frame; the pose is the scan's VIEWPOINT):
//   return     the hit point, range = true range + N(0, sigma), clamped to [0, max range]
//   no return  nothing within max range: the point kNoReturnRangeFactor x max range along the
//              beam. `bgkmap build --max-range R` with R up to the sensor's max range turns such
//              a point into a free beam of length R without a hit (OctoMap's treatment of a
//              driver's max-range reading); a build without --max-range would take it for a hit.
//   dropout    a lost return: NaN, dropped (and counted) by the mapper. A lost return carries no
//              free space, because clearing space up to max range through a wall would be wrong.
#pragma once

#include <cstdint>
#include <vector>

#include "bgkmap/core/scan.hpp"
#include "bgkmap/sim/raycaster.hpp"
#include "bgkmap/sim/sensor.hpp"

namespace bgkmap::sim {

constexpr double kNoReturnRangeFactor = 2.0;

struct ScanCounts {
  uint64_t beams = 0;
  uint64_t returns = 0;
  uint64_t no_returns = 0;
  uint64_t dropped = 0;

  ScanCounts& operator+=(const ScanCounts& o);
};

// Rotation matrix of the pose's (normalized) quaternion, in double: sensor frame -> world.
Mat3 rotation_of(const Pose& pose);

// Beam `beam` of scan `scan_index`: uniform in [0, 1) for stream 0, 1, 2, ...
double beam_uniform(uint64_t seed, uint64_t scan_index, uint64_t beam, uint32_t stream);

// `directions` are beam_directions(sensor), passed in so that they are computed once per run.
// Points come out in the order of `directions`. Runs the beams in parallel (OpenMP).
Scan simulate_scan(const Raycaster& raycaster, const SensorModel& sensor, const std::vector<Vec3d>& directions,
                   const Pose& pose, uint64_t seed, uint64_t scan_index, ScanCounts& counts);

}  // namespace bgkmap::sim
