// Warped GP regression (Snelson, Rasmussen & Ghahramani, NIPS 2004) as WGPOM (Ghaffari Jadidi et
// al., RA-L 2017) uses it: the labels y are mapped by a learned monotonic warp z = g(y) and a GP
// models z. The warp's parameters maximise the marginal likelihood of the labels, which carries
// the warp's Jacobian; predictions go back to label space by Gauss-Hermite quadrature of the
// inverse warp over the latent Gaussian. Internal header of the wgpom method (tests include it).
#pragma once

#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "core/gauss_hermite.hpp"
#include "methods/gp/gp_regression.hpp"

namespace bgkmap {

// g(y) = d y + sum_j a_j tanh(b_j (y + c_j)), d, a_j, b_j > 0: strictly increasing and onto the
// reals. Snelson's warp is the sum of tanh; the linear term makes the inverse exist at every
// quadrature node and lets the warp scale the labels down as well as up. d = 1 and no terms: the
// identity.
struct TanhWarp {
  double d = 1;
  std::vector<double> a, b, c;

  size_t terms() const { return a.size(); }
  double value(double y) const;
  double derivative(double y) const;  // g'(y) >= d
  // y with g(y) = z: Newton's method from `guess` (if inside the bracket, else z / d) kept inside
  // a bracket that shrinks (bisection where Newton leaves it); g(y) - d y lies in
  // (-sum a, sum a), which brackets the root.
  double inverse(double z, double guess = NAN) const;

  // The parameters the likelihood is differentiated by: log d, then (log a_j, log b_j, c_j) for
  // each term.
  std::vector<double> parameters() const;
  static TanhWarp from_parameters(const std::vector<double>& theta);
};

// "g(y) = 0.5 y + 1.2 tanh(0.8 (y + 0.1)) + ...", 4 significant digits.
std::string describe(const TanhWarp& warp);

// The local models a warp is learned from. The warp leaves K~ = K + sn^2 I alone and the labels
// take few values (+1, -1), so z^T K~^-1 z = sum_vw g(v) g(w) Q_vw with Q_vw = sum over the models
// of 1_v^T K~^-1 1_w (1_v: the indicator of the labels equal to v), and the likelihood's other
// terms are constants and n_v log g'(v): after one Cholesky factor per model, each evaluation
// costs O(values^2), whatever the number of models.
class WarpTrainingSet {
 public:
  WarpTrainingSet(std::vector<LocalModel> models, const GpHyperParams& hp);
  size_t size() const { return models_; }

  // sum over the models of the warped GP's log marginal likelihood of the labels (Snelson eq. 5):
  //   log p(y) = -1/2 z^T K~^-1 z - 1/2 log |K~| - n/2 log 2 pi + sum_i log g'(y_i),  z = g(y),
  // and, where asked, its gradient with respect to warp.parameters().
  double log_likelihood(const TanhWarp& warp, std::vector<double>* gradient = nullptr) const;

 private:
  size_t models_ = 0;
  std::vector<double> values_;     // the distinct label values v
  std::vector<double> counts_;     // n_v: the labels equal to v, over every model
  std::vector<double> quadratic_;  // Q, row-major
  double log_det_ = 0, labels_ = 0;
};

struct WarpLearning {
  int terms = 3;
  int restarts = 4;  // BFGS ascents: the first from a near-identity warp, the others from random starts
  int max_iterations = 200;
  uint64_t seed = 1;
  // The box the parameters are learned in (see learn_warp). b_j <= 1 keeps each tanh step at
  // least as wide as the labels are apart, so the inverse warp stays smooth enough for the
  // quadrature: wgpom's 20 Gauss-Hermite nodes are within 1e-2 of the exact integral anywhere in
  // this box (the tests check the steepest warps in it).
  double d_range[2] = {0.2, 20}, a_range[2] = {1e-3, 2}, b_range[2] = {1e-2, 1}, c_range[2] = {-2, 2};
};

// The warp maximising set.log_likelihood within the box of `options`: BFGS ascent with
// backtracking from each start (variables mapped onto the box by a logistic), the best end kept.
// The box is part of the model: labels of two values (+1, -1) fix the likelihood through g(1),
// g(-1), g'(1) and g'(-1) alone, and g' at a label can grow without bound while g(1) and g(-1)
// stay put (a steep tanh step at the label), so the unconstrained likelihood has no maximum.
// An empty set or no terms: the identity.
TanhWarp learn_warp(const WarpTrainingSet& set, const WarpLearning& options);

// The prediction in label space of a latent z ~ N(mean, variance): E[g^-1(z)] and its variance,
// by Gauss-Hermite quadrature.
GpPrediction unwarp_prediction(double mean, double variance, const TanhWarp& warp, const GaussHermite& rule);

}  // namespace bgkmap
