// The position covariances of a scan's GP training inputs under its pose uncertainty (gpom and
// wgpom, --pose-fusion kernel): from the displaced positions of the pose's sigma points
// (pose_sigma_points), so a hit far from the sensor is as uncertain as the rotation makes it.
// Internal header of those methods (tests include it).
#pragma once

#include <array>
#include <vector>

#include "bgkmap/core/pose_covariance.hpp"
#include "bgkmap/integrate/observations.hpp"
#include "methods/expected_kernel.hpp"

namespace bgkmap {

// A beam's free segment origin -> end, both ends displaced by the same rigid motion: their
// covariances and cross-covariance C_oe = Cov(origin, end) (row-major 3x3).
struct BeamCovariance {
  PositionCovariance origin, end;
  std::array<double, 9> cross{};

  // The covariance of the point at fraction t of the segment, (1 - t) o + t e:
  //   (1 - t)^2 C_oo + t^2 C_ee + t (1 - t) (C_oe + C_oe^T),
  // exact for a rigid displacement (the point moves with the segment).
  PositionCovariance at(double t) const;
};

// The sensor's noise: range (m) and bearing (rad; azimuth about z and, in 3-D, elevation about
// the horizontal axis across the beam), independent of each other and of the pose.
struct SensorNoise {
  double range_sigma = 0, bearing_sigma = 0;
  bool any() const { return range_sigma > 0 || bearing_sigma > 0; }
};

// The covariance of a return at `end` seen from `origin` under the sensor's noise, by the
// spherical-radial cubature rule (the unscented transform with kappa = 0) over (range, azimuth)
// on a planar map, (range, azimuth, elevation) otherwise: 2n points, +-sqrt(n) sigma along each,
// weights 1/(2n); each moves the return along its beam or rotates it about the origin. Planar:
// the z rows are 0.
PositionCovariance sensor_covariance(const Vec3f& origin, const Vec3f& end, const SensorNoise& noise, bool planar);

// The covariances of every hit and every beam of `obs` under `points` (empty: no pose
// uncertainty): the weighted covariance of each point's displaced positions (displace_observations'
// motion, in double; on a planar map the z displacement is dropped, so the z rows are 0), plus
// the sensor's noise (sensor_covariance) at each return, independent of the pose: a hit's and a
// beam's end's (a beam's origin has none). Appended to `hits` and `beams`.
void append_input_covariances(const ScanObservations& obs, const std::vector<PoseSigmaPoint>& points, bool planar,
                              const SensorNoise& sensor, std::vector<PositionCovariance>& hits,
                              std::vector<BeamCovariance>& beams);

}  // namespace bgkmap
