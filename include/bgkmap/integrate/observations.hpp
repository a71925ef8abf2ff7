// A scan turned into BGK-L observations: occupied end points and one free segment per beam.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/core/params.hpp"
#include "bgkmap/core/pose_covariance.hpp"
#include "bgkmap/core/scan.hpp"

namespace bgkmap {

struct ScanObservations {
  Vec3f origin;                 // start of every free segment
  std::vector<Vec3f> hits;      // y = 1: beam end points within max range
  std::vector<Vec3f> free_ends; // y = 0: free segment origin -> free_ends[i], one per beam
  // Every kernel weight of these observations is multiplied by it (the back ends scale sigma0):
  // 1, or under the expected kernel (PoseFusion::kExpectedKernel) the weight of the sigma point
  // that displaced them.
  float kernel_weight = 1.0f;
};

// `in` as seen from the pose displaced by `point` (pose_covariance.hpp): the origin, hits and
// free ends moved rigidly about in.origin (computed in double, rounded once), kernel_weight
// multiplied by the point's weight. On a planar map (`planar`) every z stays the plane's,
// in.origin.z: the displacement's component out of the plane is dropped. A hit or free end moved
// beyond the key range (within_key_range) is dropped, as preprocessing drops points there, and
// all of them when the origin is. `out` is overwritten.
void displace_observations(const ScanObservations& in, const PoseSigmaPoint& point, bool planar,
                           ScanObservations& out);

// What preprocessing saw; summed over scans into the build report.
// Without --max-range every point's beam is mapped as free space up to it. No range sensor that
// maps sees this far, and one stray point 100 km away made a 2 GB map (its beam crosses 125,000
// blocks): points farther than this from their sensor are dropped and counted instead
// (PreprocessCounts::dropped_beyond_reach); give --max-range to map such returns as free beams.
constexpr double kReachWithoutMaxRangeM = 1000;

struct PreprocessCounts {
  uint64_t points_read = 0;
  uint64_t dropped_nonfinite = 0;
  uint64_t dropped_out_of_key_range = 0;  // beyond kCoordinateLimitM (core/grid.hpp), or its scan's origin was
  uint64_t dropped_beyond_reach = 0;      // without --max-range, farther than kReachWithoutMaxRangeM from the sensor
  uint64_t removed_by_downsampling = 0;
  uint64_t beyond_max_range = 0;   // no hit: a free beam of max range, or dropped (BeyondRange)
  uint64_t no_returns = 0;          // the sensor's "no return" readings (Scan::no_return_range_m)
  uint64_t no_returns_dropped = 0;  // of those, dropped for want of a max range (the rest are beyond it)
  uint64_t hits = 0;
  uint64_t beams = 0;
  uint64_t beams_shorter_than_margin = 0;  // hit closer than the end margin: no free segment

  PreprocessCounts& operator+=(const PreprocessCounts& o);
};

// What one return becomes under the max-range policy (PreprocessParams::max_range_m and
// beyond_range), decided from its distance to the sensor origin; every method applies it.
enum class ReturnKind {
  kHit,           // within max range (or no limit): an occupied end point and its beam
  kBeyondFree,    // beyond max range, kFree: a free beam of max-range length, no hit
  kBeyondDropped  // beyond max range, kDrop: nothing
};
ReturnKind classify_return(double range_m, const PreprocessParams& params);

// The scan's points as every mapping method takes them: world frame, NaN/Inf dropped, on the
// plane of a planar map, voxel downsampled if asked; empty when the origin is not finite or beyond the key range. A "no
// return" reading (range at or beyond Scan::no_return_range_m) never becomes a hit: without a max range it is dropped; with
// one it is moved along its beam to twice the max range if it is not beyond it already, so that
// it is a beam beyond the max range like any other. Points beyond the 32-bit keys' reach
// (within_key_range, core/grid.hpp) are dropped, and so, without a max range, are points
// farther than kReachWithoutMaxRangeM from the sensor. Counts points_read, dropped_nonfinite,
// dropped_out_of_key_range, dropped_beyond_reach, removed_by_downsampling, no_returns and
// no_returns_dropped.
std::vector<Vec3f> usable_points(const Scan& scan, const PreprocessParams& params, PreprocessCounts& counts);

// A scan's usable_points, computed ahead of its insertion: the part of preprocessing that does
// not depend on the map, so that a reader thread can do it while the previous scan is mapped
// (MappingMethod::insert_prepared). Prepared for one PreprocessParams; mapped with the same.
struct PreparedScan {
  Vec3f origin;               // the scan's sensor position (on the plane of a planar map)
  std::vector<Vec3f> points;  // usable_points
  PreprocessCounts counts;    // usable_points' counts
  // The scan's pose uncertainty (Scan::pose_covariance, else PreprocessParams::pose_sigma);
  // none when it is zero.
  std::optional<PoseCovariance> pose_covariance;
  std::string pose_covariance_source;  // Scan::pose_covariance_source, or "--pose-sigma"
  double seconds = 0;         // what preparing took (part of the scan's preprocessing time)
};
PreparedScan prepare_scan(const Scan& scan, const PreprocessParams& params);

// The rest of preprocessing: hits and free ends from the prepared points, with max range
// (BeyondRange) and end margin. `out` is overwritten; its vectors keep their capacity across
// scans. Adds the prepared scan's counts and beyond_max_range, hits, beams and
// beams_shorter_than_margin to `counts`.
void observations_from(const PreparedScan& prepared, const PreprocessParams& params, ScanObservations& out,
                       PreprocessCounts& counts);

// Both: drops NaN/Inf points, optionally downsamples (voxel grid), applies max range and end margin.
void preprocess_scan(const Scan& scan, const PreprocessParams& params, ScanObservations& out,
                     PreprocessCounts& counts);

// PCL's voxel grid: one point (the centroid) per occupied leaf of size leaf_m, leaves aligned to
// multiples of leaf_m. Kept in its own translation unit so PCL's headers stay there.
std::vector<Vec3f> voxel_downsample(const std::vector<Vec3f>& points, double leaf_m);

}  // namespace bgkmap
