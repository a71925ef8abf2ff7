// gpom's local models: a query's k nearest hits (label +1) and the nearest points of its k nearest
// beams (label -1) in each pose hypothesis' training data, with the inputs' covariances under the
// expected kernel.
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

#include "methods/gp/gp_regression.hpp"
#include "methods/gpom/cell_queries.hpp"
#include "methods/gpom/training_set.hpp"

namespace bgkmap::gpom {

// How the inputs' displacements are correlated under the expected kernel (--gp-input-correlation).
enum class InputCorrelation { kIndependent, kScan, kTrajectory };

// What local models are made of; fixed while the map is evaluated.
struct LocalModelRules {
  size_t neighbours = 0;          // k: of the hits and of the beams
  double reach_m = 0;             // a query with no hit and no beam this near has no model
  bool expected_kernel = false;   // the inputs carry covariances
  bool centred = false;           // inputs relative to the query (the neural-network covariance)
  InputCorrelation correlation = InputCorrelation::kTrajectory;
  const std::vector<ScanMotion>* motions = nullptr;  // each uncertain scan's motion (correlated inputs)
  size_t motion_points = 0;                          // the most sigma points of one
};

// One thread's buffers for a query's local models.
struct Scratch {
  std::vector<uint32_t> ids;
  std::vector<float> d2;
  std::vector<NearBeam> beams;
  std::vector<Vec3d> train;
  std::vector<PositionCovariance> cov;  // expected kernel: per training input
  SharedMotion shared;                  // expected kernel with correlated inputs: their motions
  std::vector<PositionCovariance> pairs;  // ... and the covariances of their differences
  std::vector<double> labels, warped;
  std::vector<GpPrediction> parts;  // per hypothesis
  std::vector<LocalModel> models;   // per hypothesis
  std::vector<std::vector<PositionCovariance>> model_cov;    // expected kernel: per hypothesis, per input
  std::vector<std::vector<PositionCovariance>> model_pairs;  // ... per hypothesis, per pair of inputs
};

class LocalModels {
 public:
  LocalModels(const std::vector<std::unique_ptr<TrainingData>>& sets, const LocalModelRules& rules)
      : sets_(sets), rules_(rules) {}

  size_t hypotheses() const { return sets_.size(); }

  // The query's local model in `set` in s.train / s.labels (inputs in_model): false when no hit
  // and no beam is within reach.
  bool local_model(const TrainingData& set, const Vec3d& q, Scratch& s) const;

  // The local models of a query, one per hypothesis, in s.models: false (none kept) when some
  // hypothesis has no data within its reach, the cell then unknown.
  bool of_query(const Vec3d& q, Scratch& s) const;

  // Where a local model's inputs are measured from: its query for the neural-network covariance
  // (not stationary), the world's origin otherwise (x - 0 is x: the stationary maps unchanged).
  Vec3d in_model(const Vec3d& p, const Vec3d& q) const {
    const Vec3d o = rules_.centred ? q : Vec3d{0, 0, 0};
    return {p.x - o.x, p.y - o.y, p.z - o.z};
  }

  // The local models of every `stride`-th cell of the blocks (under every hypothesis), evenly
  // thinned to at most `most`, in block order.
  std::vector<LocalModel> sample(const CellQueries& queries, const std::vector<BlockKey>& blocks, int stride,
                                 size_t most, int threads) const;

 private:
  void add_shared_motion(uint32_t motion, const Vec3d& p, const Vec3d& beam_direction, SharedMotion& shared) const;

  const std::vector<std::unique_ptr<TrainingData>>& sets_;
  LocalModelRules rules_;
};

}  // namespace bgkmap::gpom
