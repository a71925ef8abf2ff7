// GP regression as gpoctomap (T-RO 2019 appendix: one test-data block, sparse kernel, a Bayesian
// committee machine fusing a cell's predictions across scans) and gpom (IJRR 2012: one local model
// per query, Matern 3/2, the sparse kernel, the squared exponential or the neural-network
// covariance, leave-one-out predictions for the PLSC fit) use it.
// Internal header of those methods (tests include it).
#pragma once

#include <array>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include "bgkmap/core/grid.hpp"

namespace bgkmap {

// Values as core/gp_kernel_math.h's selectors (the OpenCL kernel takes them).
enum class GpCovariance {
  kSparse = 0,    // bgk_math.h's sparse kernel: zero at and beyond ell
  kMatern32 = 1,  // Matern nu = 3/2: signal_var (1 + sqrt(3) d/l) exp(-sqrt(3) d/l)
  kSquaredExponential = 2,  // signal_var exp(-d^2 / (2 l^2)): its expectation under Gaussian inputs is closed form
  kNeuralNetwork = 3,       // Williams' arcsine covariance of two inputs (not stationary): gp_covariance
};

// The neural-network covariance's bias variance s0^2 (fixed: the weight of the constant input 1;
// docs/ALGORITHM.md, GPOM).
constexpr double kNeuralNetworkBiasVar = 1.0;

struct GpHyperParams {
  GpCovariance covariance = GpCovariance::kSparse;
  double ell_m = 0.2;         // length scale
  double signal_var = 0.1;    // the kernel's scale s2: k(x, x) of the stationary ones (sigma0 for the sparse kernel)
  double noise_std = 0.1;     // sigma_n: K + sigma_n^2 I
  double squash = 0.1;        // p = 1 / (1 + exp(-squash * mean / variance))
  // kNeuralNetwork with nn_sigma[0] > 0: the IJRR eq. 7 weight covariance S = diag(nn_sigma) of
  // (1, x, y, z), learned (gpom's paper mode); else S = diag(kNeuralNetworkBiasVar, 1/l^2, 1/l^2, 1/l^2).
  std::array<double, 4> nn_sigma{};
};

// The neural-network covariance's inner products a~^T S b~, a~^T S a~ and b~^T S b~.
struct NeuralNetworkTerms {
  double ab, aa, bb;
};
inline NeuralNetworkTerms neural_network_terms(const Vec3d& a, const Vec3d& b, const GpHyperParams& hp) {
  const std::array<double, 4>& s = hp.nn_sigma;
  if (s[0] > 0)
    return {s[0] + s[1] * a.x * b.x + s[2] * a.y * b.y + s[3] * a.z * b.z,
            s[0] + s[1] * a.x * a.x + s[2] * a.y * a.y + s[3] * a.z * a.z,
            s[0] + s[1] * b.x * b.x + s[2] * b.y * b.y + s[3] * b.z * b.z};
  const double inv_l2 = 1.0 / (hp.ell_m * hp.ell_m), bias = kNeuralNetworkBiasVar;
  return {bias + (a.x * b.x + a.y * b.y + a.z * b.z) * inv_l2, bias + (a.x * a.x + a.y * a.y + a.z * a.z) * inv_l2,
          bias + (b.x * b.x + b.y * b.y + b.z * b.z) * inv_l2};
}

// Sparse: k(d) = signal_var [(2 + cos(2 pi d/l))/3 (1 - d/l) + sin(2 pi d/l)/(2 pi)] for d < l, else 0.
// Matern 3/2: k(d) = signal_var (1 + sqrt(3) d/l) exp(-sqrt(3) d/l).
// Squared exponential: k(d) = signal_var exp(-d^2 / (2 l^2)).
// The stationary covariances only: throws std::invalid_argument for kNeuralNetwork.
double gp_kernel(double distance_m, const GpHyperParams& hp);

// The covariance of two inputs: gp_kernel(|a - b|) for the stationary covariances (their
// formulas, core/gp_kernel_math.h, are shared with the OpenCL solves and the expected kernel); for kNeuralNetwork (Williams 1998, as O'Callaghan & Ramos use it)
//   k(a, b) = s2 (2/pi) asin(2 a~^T S b~ / sqrt((1 + 2 a~^T S a~)(1 + 2 b~^T S b~))),
//   a~ = (1, a), S = diag(s0^2, 1/l^2, 1/l^2, 1/l^2), s0^2 = kNeuralNetworkBiasVar, or hp.nn_sigma,
// which depends on where the origin is (gpom's default mode puts it at each local model's query).
double gp_covariance(const Vec3d& a, const Vec3d& b, const GpHyperParams& hp);


// One local model's training inputs and labels.
struct LocalModel {
  std::vector<Vec3d> train;
  std::vector<double> labels;
};

class ExpectedKernel;
struct PositionCovariance;

// Training inputs with Gaussian position uncertainty (expected_kernel.hpp): input i lies at
// train[i] + N(0, covariances[i]), the test points certain. The kernel matrix is
// K_ij = E[k(x_i - x_j)] over N(train_i - train_j, D_ij) for i != j, K_ii = k(0), where D_ij is
// pair_covariances[i * n + j] when given (inputs that move together: uncertain_inputs.hpp,
// difference_covariances) and S_i + S_j (independent inputs) otherwise; a test point's covariance
// with input i is E[k] over N(train_i - test, S_i).
struct InputUncertainty {
  const std::vector<PositionCovariance>* covariances;  // one per training input
  const ExpectedKernel* kernel;                        // its hyper-parameters are the GP's
  const std::vector<PositionCovariance>* pair_covariances = nullptr;  // n x n, or none
};

// K + sn^2 I is not positive definite (inputs too close together for the noise): what gp_predict,
// gp_leave_one_out and gpom's device solves throw, naming the remedy.
class GpNotPositiveDefinite : public std::runtime_error {
 public:
  GpNotPositiveDefinite()
      : std::runtime_error("GP: the kernel matrix is not positive definite (training inputs too close together "
                           "for the noise): raise --gp-noise") {}
};

struct GpPrediction {
  double mean = 0, variance = 0;
  bool observed = false;  // some training point lies within the kernel's reach (else the prior)
};

// The GP posterior at each test point given training points with labels (+1 occupied, -1 free):
// mean k*^T (K + sn^2 I)^-1 y, variance k(x*,x*) - k*^T (K + sn^2 I)^-1 k*, by Cholesky (Eigen).
// With `uncertain`, the expected covariances above instead of k.
std::vector<GpPrediction> gp_predict(const std::vector<Vec3d>& train, const std::vector<double>& labels,
                                     const std::vector<Vec3d>& test, const GpHyperParams& hp,
                                     const InputUncertainty* uncertain = nullptr);

// Leave-one-out predictions of the training labels (R&W eq. 5.12), from K~ = K + sn^2 I:
//   mean_i = y_i - [K~^-1 y]_i / [K~^-1]_ii,   variance_i = 1 / [K~^-1]_ii.
std::vector<GpPrediction> gp_leave_one_out(const std::vector<Vec3d>& train, const std::vector<double>& labels,
                                           const GpHyperParams& hp, const InputUncertainty* uncertain = nullptr);

// One cell's fused state under the BCM: sum_k mu_k / var_k, sum_k 1 / var_k and K, so that
//   1 / var = sum_k 1 / var_k - (K - 1) / prior_var,   mean = var * sum_k mu_k / var_k.
struct BcmCell {
  double weighted_mean = 0;  // sum_k mu_k / var_k
  double precision = 0;      // sum_k 1 / var_k
  uint32_t predictions = 0;  // K

  void add(const GpPrediction& p) {
    weighted_mean += p.mean / p.variance;
    precision += 1.0 / p.variance;
    ++predictions;
  }
  double variance(double prior_var) const { return 1.0 / (precision - (predictions - 1.0) / prior_var); }
  double mean(double prior_var) const { return variance(prior_var) * weighted_mean; }
  // Logistic squashing of the variance-weighted mean (mean / variance = weighted_mean).
  double probability(double squash) const;
};

}  // namespace bgkmap
