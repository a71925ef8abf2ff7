// The covariance's hyper-parameters (length scale, signal variance, noise) learned by maximising
// the GP's log marginal likelihood over sampled local models (R&W eq. 5.8-5.9), as GPOM (IJRR
// 2012) learns them: `--gp-hyperparameters learn` of gpom and wgpom. Internal header of those
// methods (tests include it).
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "methods/gp/gp_regression.hpp"

namespace bgkmap {

// The parameters the likelihood is differentiated by: log ell, log signal_var, log noise_std.
std::vector<double> hyperparameters_vector(const GpHyperParams& hp);
GpHyperParams hyperparameters_from(const std::vector<double>& theta, const GpHyperParams& base);

// sum over the models of log p(y) = -1/2 y^T K~^-1 y - 1/2 log |K~| - n/2 log 2 pi, K~ = K + sn^2 I,
// and, where asked, its gradient 1/2 tr((a a^T - K~^-1) dK~/dtheta) (a = K~^-1 y) with respect to
// hyperparameters_vector(hp).
double gp_log_marginal_likelihood(const std::vector<LocalModel>& models, const GpHyperParams& hp,
                                  std::vector<double>* gradient = nullptr);

// pair_gradient(a, b, out): dk(a, b)/dtheta_p of a covariance's own parameters, p < kernel_params.
using PairGradient = std::function<void(const Vec3d& a, const Vec3d& b, double* out)>;
// gp_log_marginal_likelihood's sum for any covariance: with `gradient`, its kernel_params
// derivatives by pair_gradient, then the one by log noise_std.
double log_marginal_likelihood(const std::vector<LocalModel>& models, const GpHyperParams& hp, size_t kernel_params,
                               const PairGradient& pair_gradient, std::vector<double>* gradient);

struct HyperparameterLearning {
  int restarts = 3;  // the first from the given values, the others random in the box
  int max_iterations = 100;
  uint64_t seed = 1;
  // The box: ell (m), signal variance, noise standard deviation.
  double ell_range[2] = {0.05, 5}, signal_range[2] = {0.01, 100}, noise_range[2] = {0.01, 1};
};

// The hyper-parameters maximising gp_log_marginal_likelihood within the box (box_ascent), the
// covariance function kept; `start`'s values are the first start. No models: `start`.
GpHyperParams learn_hyperparameters(const std::vector<LocalModel>& models, const GpHyperParams& start,
                                    const HyperparameterLearning& options);

}  // namespace bgkmap
