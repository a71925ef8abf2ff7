#include "methods/gpom/local_models.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include "core/parallel_errors.hpp"

namespace bgkmap::gpom {

namespace {

Vec3d unit_direction(const Vec3d& a, const Vec3d& b) {
  const double n = std::sqrt(distance2(a, b));
  return {(b.x - a.x) / n, (b.y - a.y) / n, (b.z - a.z) / n};
}

}  // namespace

bool LocalModels::local_model(const TrainingData& set, const Vec3d& q, Scratch& s) const {
  s.train.clear();
  s.labels.clear();
  s.cov.clear();
  s.pairs.clear();
  const bool correlated = rules_.expected_kernel && !rules_.motions->empty();
  if (correlated) {
    s.shared.points = rules_.motion_points;
    s.shared.group.clear();
    s.shared.weight.clear();
    s.shared.moves.clear();
  }
  double nearest2 = INFINITY;
  set.hits.nearest(q, rules_.neighbours, s.ids, s.d2);
  for (const uint32_t id : s.ids) {
    const Vec3d hit = to_d(set.hits[id]);
    s.train.push_back(in_model(hit, q));
    s.labels.push_back(1.0);
    if (rules_.expected_kernel) s.cov.push_back(set.hit_cov[id]);
    if (correlated) add_shared_motion(set.hit_motion[id], hit, Vec3d{}, s.shared);
    nearest2 = std::min(nearest2, distance2(q, hit));
  }
  if (set.beam_samples.size() > 0) nearest_beams(set, q, rules_.neighbours, s.beams, s.ids, s.d2);
  else s.beams.clear();
  for (const NearBeam& b : s.beams) {
    s.train.push_back(in_model(b.point, q));
    s.labels.push_back(-1.0);
    if (rules_.expected_kernel) {
      // Inside the segment the nearest point moves only across it (across_segment).
      Vec3d beam_direction{};
      PositionCovariance c = set.beam_cov[b.beam].at(b.t);
      if (b.t > 0 && b.t < 1) {
        beam_direction = unit_direction(to_d(set.beam_origins[b.beam]), to_d(set.beam_ends[b.beam]));
        c = across_segment(c, beam_direction);
      }
      s.cov.push_back(c);
      if (correlated) add_shared_motion(set.beam_motion[b.beam], b.point, beam_direction, s.shared);
    }
    nearest2 = std::min(nearest2, b.d2);
  }
  if (correlated) difference_covariances(s.cov, s.shared, s.pairs);
  return nearest2 <= rules_.reach_m * rules_.reach_m;
}

// An input's centred displacements under its scan's sigma points (zero past their number;
// their part along `beam_direction` removed: a segment's inner point, zero for a hit) and its
// group: its scan's motion, or one group for every uncertain scan when they are paired
// (trajectory).
void LocalModels::add_shared_motion(uint32_t motion, const Vec3d& p, const Vec3d& beam_direction,
                                    SharedMotion& shared) const {
  const size_t first = shared.moves.size();
  shared.moves.resize(first + shared.points);
  if (motion == SharedMotion::kNoGroup) {
    shared.group.push_back(SharedMotion::kNoGroup);
    shared.weight.push_back(0.0);
    return;
  }
  const ScanMotion& m = (*rules_.motions)[motion];
  Vec3d* d = &shared.moves[first];
  m.displacements(p, d);
  Vec3d mean;
  for (size_t h = 0; h < m.size(); ++h) {
    const Vec3d& u = beam_direction;
    const double along = d[h].x * u.x + d[h].y * u.y + d[h].z * u.z;
    d[h] = {d[h].x - along * u.x, d[h].y - along * u.y, d[h].z - along * u.z};
    const double w = m.weights()[h];
    mean = {mean.x + w * d[h].x, mean.y + w * d[h].y, mean.z + w * d[h].z};
  }
  for (size_t h = 0; h < m.size(); ++h) d[h] = {d[h].x - mean.x, d[h].y - mean.y, d[h].z - mean.z};
  shared.group.push_back(rules_.correlation == InputCorrelation::kTrajectory ? 0 : motion);
  shared.weight.push_back(m.weights()[0]);
}

bool LocalModels::of_query(const Vec3d& q, Scratch& s) const {
  s.models.resize(sets_.size());
  s.model_cov.resize(sets_.size());
  s.model_pairs.resize(sets_.size());
  for (size_t h = 0; h < sets_.size(); ++h) {
    if (!local_model(*sets_[h], q, s)) return false;
    s.models[h].train.swap(s.train);
    s.models[h].labels.swap(s.labels);
    s.model_cov[h].swap(s.cov);
    s.model_pairs[h].swap(s.pairs);
  }
  return true;
}

std::vector<LocalModel> LocalModels::sample(const CellQueries& queries, const std::vector<BlockKey>& blocks,
                                            int stride, size_t most, int threads) const {
  std::vector<std::vector<LocalModel>> sampled(blocks.size());
  ParallelErrors errors;
#pragma omp parallel for schedule(dynamic) num_threads(threads)
  for (int64_t b = 0; b < static_cast<int64_t>(blocks.size()); ++b)
    errors.run([&] {
      Scratch s;
      queries.for_each_query(blocks[b], stride, [&](int, const Vec3d& q) {
        for (const auto& set : sets_)
          if (local_model(*set, q, s)) sampled[b].push_back({s.train, s.labels});
      });
    });
  errors.rethrow();
  std::vector<LocalModel> models;
  for (std::vector<LocalModel>& block : sampled)
    for (LocalModel& model : block) models.push_back(std::move(model));
  const size_t keep_every = (models.size() + most - 1) / most;
  std::vector<LocalModel> kept;
  for (size_t i = 0; i < models.size(); i += std::max<size_t>(keep_every, 1)) kept.push_back(std::move(models[i]));
  return kept;
}

}  // namespace bgkmap::gpom
