// gpom's training data: every scan's hits (label +1) and beams' free segments (label -1) as one
// pose hypothesis places them, with the k-d trees that find a query's nearest of each.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/integrate/observations.hpp"
#include "methods/gp/expected_kernel.hpp"
#include "methods/gpom/growing_tree.hpp"
#include "methods/gp/uncertain_inputs.hpp"

namespace bgkmap::gpom {

inline double distance2(const Vec3d& a, const Vec3d& b) {
  const double dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  return dx * dx + dy * dy + dz * dz;
}
inline Vec3d to_d(const Vec3f& p) { return {p.x, p.y, p.z}; }

// The training data of every scan so far, as one pose hypothesis places it.
struct TrainingData {
  GrowingTree hits, beam_samples;
  std::vector<Vec3f> beam_origins, beam_ends;  // per beam: its free segment
  std::vector<uint32_t> sample_beam;           // per beam sample: its beam
  // Under the expected kernel, once a scan is uncertain: per hit and per beam (zero for certain scans).
  std::vector<PositionCovariance> hit_cov;
  std::vector<BeamCovariance> beam_cov;
  // Under the expected kernel with correlated inputs: per hit and per beam its scan's motion
  // (an index into the method's motions), SharedMotion::kNoGroup for a certain scan.
  std::vector<uint32_t> hit_motion, beam_motion;
};

// The equal pieces a beam from a to b is sampled in, none longer than step_m.
int beam_pieces(const Vec3d& a, const Vec3d& b, double step_m);

// Appends a scan's hits and beams (already placed by its hypothesis) to `set`, each beam sampled
// at the midpoints of its beam_pieces.
void add_training(const ScanObservations& obs, double beam_step_m, TrainingData& set);

// What adding `obs` to `copies` sets like `set` may allocate, in bytes (the memory limit's check):
// with `covariances` the expected kernel's per input, with `motion_links` each input's link to its
// scan's motion.
double training_bytes(const TrainingData& set, double copies, const ScanObservations& obs, double beam_step_m,
                      bool covariances, bool motion_links);

// A beam near a query: its point nearest to the query, at fraction t along it, d2 away.
struct NearBeam {
  double d2;
  uint32_t beam;
  double t;
  Vec3d point;
  bool operator<(const NearBeam& o) const { return d2 < o.d2 || (d2 == o.d2 && beam < o.beam); }
};

// The query's k nearest beams, nearest first, by their segment's exact distance to q (ids, d2:
// the caller's scratch for the tree search).
void nearest_beams(const TrainingData& set, const Vec3d& q, size_t k, std::vector<NearBeam>& beams,
                   std::vector<uint32_t>& ids, std::vector<float>& d2);

// The fraction t along the beam (origin 0, end 1) of its point nearest to q.
double beam_fraction(const TrainingData& set, const Vec3d& q, uint32_t beam);
Vec3d point_on_beam(const TrainingData& set, uint32_t beam, double t);

}  // namespace bgkmap::gpom
