// A gpom cell from its local models: each hypothesis' GP regression at the query (gp_regression,
// the expected kernel's when the inputs are uncertain), in label space, and their moment-matched
// mixture; the models' leave-one-out predictions for the PLSC fit.
#pragma once

#include <vector>

#include "methods/gp/expected_kernel.hpp"
#include "methods/gpom/cell_queries.hpp"
#include "methods/gpom/label_warp.hpp"
#include "methods/gpom/local_models.hpp"
#include "methods/gp/plsc.hpp"

namespace bgkmap::gpom {

// The moment-matched Gaussian of an equal-weight mixture of predictions.
GpPrediction mixture_moments(const std::vector<GpPrediction>& parts);

class CellSolver {
 public:
  // kernel: the expected kernel over uncertain inputs, or null (the plain one). prior_far: a
  // query with no datum within reach is at the GP prior (paper mode), else unknown.
  CellSolver(const GpHyperParams& hp, const ExpectedKernel* kernel, const LabelWarp& warp, const LocalModels& models,
             bool prior_far = false)
      : hp_(hp), kernel_(kernel), warp_(warp), models_(models), prior_far_(prior_far) {}

  const LabelWarp& warp() const { return warp_; }

  // Hypothesis h's latent prediction at q from its local model in s (of_query's).
  GpPrediction latent(Scratch& s, size_t h, const Vec3d& q) const;

  // The leave-one-out samples of the local models in s, in label space.
  void sample_leave_one_out(const Scratch& s, std::vector<LooSample>& out) const;

  // A known cell from its hypotheses' latent predictions.
  GpomCell cell_of(const std::vector<GpPrediction>& latent, Scratch& s) const;

  // A query with no datum within reach: the GP prior, mean 0 and variance k(q, q), in label space
  // (prior_far), or an unknown cell.
  GpomCell unreached(const Vec3d& q) const;

 private:
  InputUncertainty uncertainty(const Scratch& s, size_t h) const {
    return {&s.model_cov[h], kernel_, s.model_pairs[h].empty() ? nullptr : &s.model_pairs[h]};
  }

  const GpHyperParams& hp_;
  const ExpectedKernel* kernel_;
  const LabelWarp& warp_;
  const LocalModels& models_;
  bool prior_far_;
};

}  // namespace bgkmap::gpom
