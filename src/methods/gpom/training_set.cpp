#include "methods/gpom/training_set.hpp"

#include <algorithm>
#include <cmath>

namespace bgkmap::gpom {

int beam_pieces(const Vec3d& a, const Vec3d& b, double step_m) {
  return std::max(1, static_cast<int>(std::ceil(std::sqrt(distance2(a, b)) / step_m)));
}

void add_training(const ScanObservations& obs, double beam_step_m, TrainingData& set) {
  set.hits.add(obs.hits);
  std::vector<Vec3f> samples;
  for (const Vec3f& end : obs.free_ends) {
    const uint32_t beam = static_cast<uint32_t>(set.beam_ends.size());
    set.beam_ends.push_back(end);
    set.beam_origins.push_back(obs.origin);
    // The midpoints of equal pieces no longer than beam_step_m: every point of the beam is
    // within beam_step_m / 2 of a sample (nearest_beams), and the scan's beams share no sample
    // at the origin (a k-d tree cannot split a pile of equal points).
    const Vec3d a = to_d(obs.origin), b = to_d(end);
    const int pieces = beam_pieces(a, b, beam_step_m);
    for (int i = 0; i < pieces; ++i) {
      const double t = (i + 0.5) / pieces;
      samples.push_back({static_cast<float>(a.x + t * (b.x - a.x)), static_cast<float>(a.y + t * (b.y - a.y)),
                         static_cast<float>(a.z + t * (b.z - a.z))});
      set.sample_beam.push_back(beam);
    }
  }
  set.beam_samples.add(samples);
}

// Every scan's hits and beam samples stay (with their k-d trees) for the whole build. A growing
// array holds its old and new buffers for a moment, so its doubling costs the whole new buffer;
// each k-d tree keeps an index and nodes (about 10 bytes a point), and is rebuilt with its new
// index (4 bytes a point) made while the old tree still stands.
double training_bytes(const TrainingData& d, double copies, const ScanObservations& obs, double beam_step_m,
                      bool covariances, bool motion_links) {
  constexpr double kTreeBytesPerPoint = 10, kTreeIndexBytesPerPoint = 4;
  const Vec3d a = to_d(obs.origin);
  double samples = 0;
  for (const Vec3f& end : obs.free_ends) samples += beam_pieces(a, to_d(end), beam_step_m);
  const double hits = double(obs.hits.size()), beams = double(obs.free_ends.size());
  const auto growth = [](size_t size, size_t capacity, double more, size_t element_bytes) {
    const double needed = double(size) + more;
    return needed > double(capacity) ? std::max(2.0 * double(capacity), needed) * double(element_bytes) : 0.0;
  };
  // The expected kernel's covariances, from the first uncertain scan on (which fills in the
  // earlier scans' zeros).
  const double covariance_bytes =
      covariances ? growth(d.hit_cov.size(), d.hit_cov.capacity(), double(d.hits.size() - d.hit_cov.size()) + hits,
                           sizeof(PositionCovariance)) +
                        growth(d.beam_cov.size(), d.beam_cov.capacity(),
                               double(d.beam_ends.size() - d.beam_cov.size()) + beams, sizeof(BeamCovariance))
                  : 0.0;
  const double motion_bytes =
      motion_links ? growth(d.hit_motion.size(), d.hit_motion.capacity(), double(d.hits.size() - d.hit_motion.size()) + hits,
                            sizeof(uint32_t)) +
                         growth(d.beam_motion.size(), d.beam_motion.capacity(),
                                double(d.beam_ends.size() - d.beam_motion.size()) + beams, sizeof(uint32_t))
                   : 0.0;
  // Every hypothesis' copy grows alike.
  return covariance_bytes + motion_bytes +
         copies * (growth(d.hits.size(), d.hits.capacity(), hits, sizeof(Vec3f)) +
                   growth(d.beam_samples.size(), d.beam_samples.capacity(), samples, sizeof(Vec3f)) +
                   growth(d.sample_beam.size(), d.sample_beam.capacity(), samples, sizeof(uint32_t)) +
                   growth(d.beam_ends.size(), d.beam_ends.capacity(), beams, sizeof(Vec3f)) +
                   growth(d.beam_origins.size(), d.beam_origins.capacity(), beams, sizeof(Vec3f)) +
                   (hits + samples) * kTreeBytesPerPoint +
                   (double(d.hits.size() + d.beam_samples.size()) + hits + samples) * kTreeIndexBytesPerPoint);
}

// The candidates: the beams of the query's 4k nearest beam samples. Every point of a beam lies
// within beam_step_m / 2 of one of its samples, so a beam left out is at most that much nearer
// than the farthest candidate sample; with at most 4k samples in all, none is left out.
void nearest_beams(const TrainingData& set, const Vec3d& q, size_t k, std::vector<NearBeam>& beams,
                   std::vector<uint32_t>& ids, std::vector<float>& d2) {
  const size_t found = set.beam_samples.nearest(q, 4 * k, ids, d2);
  beams.clear();
  for (size_t i = 0; i < found; ++i) beams.push_back({0.0, set.sample_beam[ids[i]], 0.0, {}});
  std::sort(beams.begin(), beams.end(), [](const NearBeam& a, const NearBeam& b) { return a.beam < b.beam; });
  beams.erase(std::unique(beams.begin(), beams.end(), [](const NearBeam& a, const NearBeam& b) { return a.beam == b.beam; }),
              beams.end());
  for (NearBeam& b : beams) {
    b.t = beam_fraction(set, q, b.beam);
    b.point = point_on_beam(set, b.beam, b.t);
    b.d2 = distance2(q, b.point);
  }
  std::sort(beams.begin(), beams.end());
  if (beams.size() > k) beams.resize(k);
}

double beam_fraction(const TrainingData& set, const Vec3d& q, uint32_t beam) {
  const Vec3d a = to_d(set.beam_origins[beam]), b = to_d(set.beam_ends[beam]);
  const Vec3d ab{b.x - a.x, b.y - a.y, b.z - a.z};
  const double len2 = ab.x * ab.x + ab.y * ab.y + ab.z * ab.z;
  return len2 > 0 ? std::clamp(((q.x - a.x) * ab.x + (q.y - a.y) * ab.y + (q.z - a.z) * ab.z) / len2, 0.0, 1.0) : 0.0;
}

Vec3d point_on_beam(const TrainingData& set, uint32_t beam, double t) {
  const Vec3d a = to_d(set.beam_origins[beam]), b = to_d(set.beam_ends[beam]);
  return {a.x + t * (b.x - a.x), a.y + t * (b.y - a.y), a.z + t * (b.z - a.z)};
}

}  // namespace bgkmap::gpom
