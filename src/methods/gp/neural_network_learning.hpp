// The IJRR paper's hyper-parameters of its neural-network covariance (eq. 7, Sigma learned in the
// global frame): the log marginal likelihood (eq. 9) of one training set maximised by a global
// search, then a local one (IJRR sec. 3.2: simulated annealing, then L-BFGS; here NLopt's CRS2
// and L-BFGS). gpom's paper mode (--gp-mode paper). Internal header (tests include it).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "methods/gp/gp_regression.hpp"

namespace bgkmap {

// The parameters the likelihood is differentiated by, for inputs of `dims` (2 or 3) coordinates:
// log s2, log Sigma_0 (the bias), log Sigma_1 .. log Sigma_dims, log sn. In 2-D Sigma_3 is 0.
std::vector<double> neural_network_vector(const GpHyperParams& hp, int dims);
GpHyperParams neural_network_from(const std::vector<double>& theta, const GpHyperParams& base, int dims);

// log p(y) of the model under hp (kNeuralNetwork, nn_sigma set) and, where asked, its gradient
// with respect to neural_network_vector(hp, dims).
double neural_network_log_likelihood(const LocalModel& model, const GpHyperParams& hp, int dims,
                                     std::vector<double>* gradient = nullptr);

struct NeuralNetworkLearning {
  int dims = 2;
  int global_evaluations = 200;  // CRS2 (stochastic, seeded)
  int local_evaluations = 100;   // L-BFGS from the best point found
  uint64_t seed = 1;
  // The box, for the global search and bounding the local one.
  double signal_range[2] = {0.01, 100}, noise_range[2] = {0.01, 1};
  double bias_range[2] = {1e-3, 1e3}, weight_range[2] = {1e-4, 1e2};  // Sigma_0; Sigma_1.. (1 / m^2)
};

// The hyper-parameters maximising neural_network_log_likelihood on `training` within the box;
// `start` (made explicit: its nn_sigma set from its length if unset) is the first point tried.
// No training point: `start`.
GpHyperParams learn_neural_network(const LocalModel& training, GpHyperParams start,
                                   const NeuralNetworkLearning& options);

// S = diag(kNeuralNetworkBiasVar, 1/l^2, 1/l^2, 1/l^2 or 0 in 2-D): the default-mode covariance
// with an explicit Sigma.
std::array<double, 4> neural_network_sigma_of_length(double ell_m, int dims);

}  // namespace bgkmap
