#include "methods/gp/neural_network_learning.hpp"

#include <nlopt.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "methods/gp/gp_hyperparameters.hpp"

namespace bgkmap {

namespace {

constexpr double kTwoOverPi = 0.6366197723675814;

// With ta = (1, a), A = 1 + 2 ta^T S ta, B likewise, z = 2 ta^T S tb / sqrt(AB): per dlog S_p,
// d(ta^T S tb) = S_p ta_p tb_p, dA = 2 S_p ta_p^2, so dz = 2 S_p ta_p tb_p / sqrt(AB) -
// z (S_p ta_p^2 / A + S_p tb_p^2 / B), and dk = s2 (2/pi) dz / sqrt(1 - z^2); dk/dlog s2 = k.
void pair_gradient(const Vec3d& a, const Vec3d& b, const GpHyperParams& hp, int dims, double* out) {
  const NeuralNetworkTerms t = neural_network_terms(a, b, hp);
  const double big_a = 1 + 2 * t.aa, big_b = 1 + 2 * t.bb, root = std::sqrt(big_a * big_b);
  const double z = 2 * t.ab / root, scale = hp.signal_var * kTwoOverPi / std::sqrt(1 - z * z);
  out[0] = hp.signal_var * kTwoOverPi * std::asin(z);
  const double ta[4] = {1, a.x, a.y, a.z}, tb[4] = {1, b.x, b.y, b.z};
  for (int p = 0; p <= dims; ++p) {
    const double s = hp.nn_sigma[size_t(p)];
    out[1 + p] = scale * (2 * s * ta[p] * tb[p] / root - z * (s * ta[p] * ta[p] / big_a + s * tb[p] * tb[p] / big_b));
  }
}

struct Search {
  const LocalModel& model;
  const GpHyperParams& base;
  int dims;
  std::vector<double> best;
  double best_value = -std::numeric_limits<double>::infinity();
};

// NLopt maximises this; a point where K~ is not positive definite is the worst (no gradient).
double objective(const std::vector<double>& theta, std::vector<double>& gradient, void* data) {
  Search& search = *static_cast<Search*>(data);
  std::vector<double> g;
  double value = -std::numeric_limits<double>::max();
  try {
    const GpHyperParams hp = neural_network_from(theta, search.base, search.dims);
    value = neural_network_log_likelihood(search.model, hp, search.dims, gradient.empty() ? nullptr : &g);
  } catch (const GpNotPositiveDefinite&) {
    g.assign(theta.size(), 0.0);
  }
  if (!std::isfinite(value)) value = -std::numeric_limits<double>::max();
  if (!gradient.empty()) gradient = g;
  if (value > search.best_value) search.best_value = value, search.best = theta;
  return value;
}

void run(nlopt::algorithm algorithm, int evaluations, const std::vector<double>& lo, const std::vector<double>& hi,
         std::vector<double> x, Search& search) {
  nlopt::opt opt(algorithm, static_cast<unsigned>(x.size()));
  opt.set_lower_bounds(lo);
  opt.set_upper_bounds(hi);
  opt.set_maxeval(evaluations);
  opt.set_max_objective(objective, &search);
  opt.set_xtol_rel(1e-6);
  double value = 0;
  try {
    opt.optimize(x, value);
  } catch (const std::runtime_error&) {
    // round-off limits and failures of a step: the best point so far stands
  }
}

}  // namespace

std::array<double, 4> neural_network_sigma_of_length(double ell_m, int dims) {
  const double w = 1.0 / (ell_m * ell_m);
  return {kNeuralNetworkBiasVar, w, w, dims == 3 ? w : 0.0};
}

std::vector<double> neural_network_vector(const GpHyperParams& hp, int dims) {
  std::vector<double> theta{std::log(hp.signal_var)};
  for (int p = 0; p <= dims; ++p) theta.push_back(std::log(hp.nn_sigma[size_t(p)]));
  theta.push_back(std::log(hp.noise_std));
  return theta;
}

GpHyperParams neural_network_from(const std::vector<double>& theta, const GpHyperParams& base, int dims) {
  if (theta.size() != size_t(dims) + 3) throw std::invalid_argument("neural network: dims + 3 parameters");
  GpHyperParams hp = base;
  hp.covariance = GpCovariance::kNeuralNetwork;
  hp.signal_var = std::exp(theta[0]);
  hp.nn_sigma = {0, 0, 0, 0};
  for (int p = 0; p <= dims; ++p) hp.nn_sigma[size_t(p)] = std::exp(theta[size_t(1 + p)]);
  hp.noise_std = std::exp(theta.back());
  return hp;
}

double neural_network_log_likelihood(const LocalModel& model, const GpHyperParams& hp, int dims,
                                     std::vector<double>* gradient) {
  if (hp.covariance != GpCovariance::kNeuralNetwork || !(hp.nn_sigma[0] > 0))
    throw std::invalid_argument("neural network likelihood: the covariance must be nn with Sigma set");
  const PairGradient by_pair = [&hp, dims](const Vec3d& a, const Vec3d& b, double* out) {
    pair_gradient(a, b, hp, dims, out);
  };
  return log_marginal_likelihood({model}, hp, size_t(dims) + 2, by_pair, gradient);
}

GpHyperParams learn_neural_network(const LocalModel& training, GpHyperParams start,
                                   const NeuralNetworkLearning& options) {
  const int dims = options.dims;
  start.covariance = GpCovariance::kNeuralNetwork;
  if (!(start.nn_sigma[0] > 0)) start.nn_sigma = neural_network_sigma_of_length(start.ell_m, dims);
  if (training.labels.empty()) return start;
  std::vector<double> lo{std::log(options.signal_range[0])}, hi{std::log(options.signal_range[1])};
  for (int p = 0; p <= dims; ++p) {
    const double* range = p == 0 ? options.bias_range : options.weight_range;
    lo.push_back(std::log(range[0]));
    hi.push_back(std::log(range[1]));
  }
  lo.push_back(std::log(options.noise_range[0]));
  hi.push_back(std::log(options.noise_range[1]));
  std::vector<double> x0 = neural_network_vector(start, dims);
  for (size_t k = 0; k < x0.size(); ++k) x0[k] = std::min(std::max(x0[k], lo[k]), hi[k]);
  Search search{training, start, dims, x0, -std::numeric_limits<double>::infinity()};
  nlopt::srand(options.seed);  // CRS2's random population: the same seed, the same search
  run(nlopt::GN_CRS2_LM, options.global_evaluations, lo, hi, x0, search);
  run(nlopt::LD_LBFGS, options.local_evaluations, lo, hi, search.best, search);
  return neural_network_from(search.best, start, dims);
}

}  // namespace bgkmap
