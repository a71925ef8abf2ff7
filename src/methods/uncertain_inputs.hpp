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

// The covariances of every hit and every beam of `obs` under `points` (empty: all zero): the
// weighted covariance of each point's displaced positions (displace_observations' motion, in
// double; on a planar map the z displacement is dropped, so the z rows are 0). Appended to
// `hits` and `beams`.
void append_input_covariances(const ScanObservations& obs, const std::vector<PoseSigmaPoint>& points, bool planar,
                              std::vector<PositionCovariance>& hits, std::vector<BeamCovariance>& beams);

}  // namespace bgkmap
