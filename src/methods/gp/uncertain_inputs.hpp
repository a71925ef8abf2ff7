// The position covariances of a scan's GP training inputs under its pose uncertainty (gpom and
// wgpom, --pose-fusion kernel): from the displaced positions of the pose's sigma points
// (pose_sigma_points), so a hit far from the sensor is as uncertain as the rotation makes it.
// Internal header of those methods (tests include it).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "bgkmap/core/pose_covariance.hpp"
#include "bgkmap/integrate/observations.hpp"
#include "methods/gp/expected_kernel.hpp"

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

// The rigid motion of a scan under each of its pose's sigma points: a point p seen from the
// estimated pose moves by t_h + (R_h - I)(p - o) (displace_observations' motion, in double; on a
// planar map the z displacement is dropped).
class ScanMotion {
 public:
  ScanMotion() = default;
  ScanMotion(const Vec3f& origin, const std::vector<PoseSigmaPoint>& points, bool planar);

  size_t size() const { return weights_.size(); }
  const std::vector<double>& weights() const { return weights_; }
  // p's displacement under each sigma point, in out[0..size()).
  void displacements(const Vec3d& p, Vec3d* out) const;

 private:
  Vec3d origin_;
  bool planar_ = false;
  std::vector<double> weights_;
  std::vector<Vec3d> translations_;
  std::vector<std::array<double, 9>> rotations_;
};

// The covariance of the point of a free segment nearest to a query, where that point is inside the
// segment: (I - u u^T) C (I - u u^T), C the covariance of the segment's point there (BeamCovariance::at)
// and u the segment's unit direction. Under a small motion of the segment the nearest point moves
// only across it (to first order): a motion along the segment leaves the nearest point where it
// is. Each end keeps its whole covariance.
PositionCovariance across_segment(const PositionCovariance& c, const Vec3d& unit_direction);

// Inputs whose positions move together: those of one group share one motion's sigma points
// (one scan's, or every scan's with their h-th points paired), input i by moves[i * points + h]
// under point h (centred: their weighted mean subtracted), of weight weight[i] (one group, one
// weight). Input i in no group (kNoGroup) is independent of all others.
struct SharedMotion {
  static constexpr uint32_t kNoGroup = UINT32_MAX;
  size_t points = 0;
  std::vector<uint32_t> group;
  std::vector<double> weight;
  std::vector<Vec3d> moves;
};

// The covariance of x_i - x_j for every pair of inputs (out: n x n, row-major; the diagonal is
// not used): S_i + S_j (`marginal`, each input's own covariance, sensor noise included), less
// C_ij + C_ij^T, C_ij = sum_h w_h d_ih d_jh^T, when i and j move together (one group). So two hits
// of one scan, which a rotation moves alike, keep a nearly certain difference.
void difference_covariances(const std::vector<PositionCovariance>& marginal, const SharedMotion& shared,
                            std::vector<PositionCovariance>& out);

// The covariances of every hit and every beam of `obs` under `points` (empty: no pose
// uncertainty): the weighted covariance of each point's displaced positions (displace_observations'
// motion, in double; on a planar map the z displacement is dropped, so the z rows are 0), plus
// the sensor's noise (sensor_covariance) at each return, independent of the pose: a hit's and a
// beam's end's (a beam's origin has none). Appended to `hits` and `beams`.
void append_input_covariances(const ScanObservations& obs, const std::vector<PoseSigmaPoint>& points, bool planar,
                              const SensorNoise& sensor, std::vector<PositionCovariance>& hits,
                              std::vector<BeamCovariance>& beams);

}  // namespace bgkmap
