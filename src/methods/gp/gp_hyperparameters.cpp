#include "methods/gp/gp_hyperparameters.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "core/splitmix.hpp"
#include "methods/bhm/box_ascent.hpp"
#include "methods/gp/gp_cholesky.hpp"

namespace bgkmap {

namespace {

constexpr double kLog2Pi = 1.8378770664093453;

// dk/dlog ell of a stationary covariance at distance d (dk/dlog signal_var is k itself).
double kernel_d_log_ell(double d, const GpHyperParams& hp) {
  if (hp.covariance == GpCovariance::kMatern32) {
    const double r = 1.7320508075688772 * d / hp.ell_m;  // dk/dr = -s2 r exp(-r), dr/dlog ell = -r
    return hp.signal_var * r * r * std::exp(-r);
  }
  if (hp.covariance == GpCovariance::kSquaredExponential) {
    const double x = d / hp.ell_m;  // dk/dlog ell = k x^2
    return hp.signal_var * std::exp(-0.5 * x * x) * x * x;
  }
  if (d >= hp.ell_m) return 0;
  const double two_pi = 6.283185307179586, x = d / hp.ell_m;
  const double dk_dx = hp.signal_var * (-two_pi * std::sin(two_pi * x) * (1 - x) / 3 + (2 * std::cos(two_pi * x) - 2) / 3);
  return -x * dk_dx;  // dx/dlog ell = -x
}

// dk(a, b)/dlog ell of the neural-network covariance (gp_regression.hpp): with p = a.b / l^2,
// pa = |a|^2 / l^2, pb = |b|^2 / l^2, A = 1 + 2 (s0^2 + pa), B = 1 + 2 (s0^2 + pb) and
// z = 2 (s0^2 + p) / sqrt(AB), per dlog ell dp = -2p, dA = -4 pa, dB = -4 pb, so
// dz = -4p / sqrt(AB) + 2z (pa / A + pb / B), and dk = s2 (2/pi) dz / sqrt(1 - z^2).
double neural_network_d_log_ell(const Vec3d& a, const Vec3d& b, const GpHyperParams& hp) {
  const double inv_l2 = 1.0 / (hp.ell_m * hp.ell_m), bias = kNeuralNetworkBiasVar;
  const double p = (a.x * b.x + a.y * b.y + a.z * b.z) * inv_l2;
  const double pa = (a.x * a.x + a.y * a.y + a.z * a.z) * inv_l2, pb = (b.x * b.x + b.y * b.y + b.z * b.z) * inv_l2;
  const double big_a = 1 + 2 * (bias + pa), big_b = 1 + 2 * (bias + pb), root = std::sqrt(big_a * big_b);
  const double z = 2 * (bias + p) / root;
  const double dz = -4 * p / root + 2 * z * (pa / big_a + pb / big_b);
  return hp.signal_var * 0.6366197723675814 * dz / std::sqrt(1 - z * z);
}

double covariance_d_log_ell(const Vec3d& a, const Vec3d& b, const GpHyperParams& hp) {
  if (hp.covariance == GpCovariance::kNeuralNetwork) return neural_network_d_log_ell(a, b, hp);
  const double dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  return kernel_d_log_ell(std::sqrt(dx * dx + dy * dy + dz * dz), hp);
}

}  // namespace

std::vector<double> hyperparameters_vector(const GpHyperParams& hp) {
  return {std::log(hp.ell_m), std::log(hp.signal_var), std::log(hp.noise_std)};
}

GpHyperParams hyperparameters_from(const std::vector<double>& theta, const GpHyperParams& base) {
  GpHyperParams hp = base;
  hp.ell_m = std::exp(theta.at(0));
  hp.signal_var = std::exp(theta.at(1));
  hp.noise_std = std::exp(theta.at(2));
  return hp;
}

double log_marginal_likelihood(const std::vector<LocalModel>& models, const GpHyperParams& hp, size_t kernel_params,
                               const PairGradient& pair_gradient, std::vector<double>* gradient) {
  if (gradient) gradient->assign(kernel_params + 1, 0.0);
  double sum = 0;
  std::vector<double> pair(kernel_params), local(kernel_params);
  for (const LocalModel& m : models) {
    const Eigen::Index n = static_cast<Eigen::Index>(m.labels.size());
    const Eigen::LLT<Eigen::MatrixXd> llt = gp_factor(m.train, hp);
    const Eigen::VectorXd alpha = llt.solve(Eigen::Map<const Eigen::VectorXd>(m.labels.data(), n));
    sum += -0.5 * Eigen::Map<const Eigen::VectorXd>(m.labels.data(), n).dot(alpha) -
           llt.matrixLLT().diagonal().array().log().sum() - 0.5 * n * kLog2Pi;
    if (!gradient) continue;
    // W = a a^T - K~^-1; dL/dtheta = 1/2 sum_ij W_ij dK~_ij/dtheta.
    const Eigen::MatrixXd w = alpha * alpha.transpose() - llt.solve(Eigen::MatrixXd::Identity(n, n));
    local.assign(kernel_params, 0.0);
    for (Eigen::Index i = 0; i < n; ++i)
      for (Eigen::Index j = 0; j < n; ++j) {
        pair_gradient(m.train[i], m.train[j], pair.data());
        for (size_t p = 0; p < kernel_params; ++p) local[p] += w(i, j) * pair[p];
      }
    for (size_t p = 0; p < kernel_params; ++p) (*gradient)[p] += 0.5 * local[p];
    (*gradient)[kernel_params] += 0.5 * w.trace() * 2 * hp.noise_std * hp.noise_std;  // dK~/dlog sn = 2 sn^2 I
  }
  return sum;
}

double gp_log_marginal_likelihood(const std::vector<LocalModel>& models, const GpHyperParams& hp,
                                  std::vector<double>* gradient) {
  const PairGradient ell_and_signal = [&hp](const Vec3d& a, const Vec3d& b, double* out) {
    out[0] = covariance_d_log_ell(a, b, hp);
    out[1] = gp_covariance(a, b, hp);  // dk/dlog s2 = k
  };
  return log_marginal_likelihood(models, hp, 2, ell_and_signal, gradient);
}

GpHyperParams learn_hyperparameters(const std::vector<LocalModel>& models, const GpHyperParams& start,
                                    const HyperparameterLearning& options) {
  if (models.empty()) return start;
  const Box box{{std::log(options.ell_range[0]), std::log(options.signal_range[0]), std::log(options.noise_range[0])},
                {std::log(options.ell_range[1]), std::log(options.signal_range[1]), std::log(options.noise_range[1])}};
  std::vector<std::vector<double>> starts{hyperparameters_vector(start)};
  uint64_t counter = options.seed * 1000003 + 7;
  for (int restart = 1; restart < options.restarts; ++restart) {
    std::vector<double> theta(3);
    for (size_t k = 0; k < 3; ++k) theta[k] = box.lo[k] + (box.hi[k] - box.lo[k]) * unit_interval(splitmix64(counter++));
    starts.push_back(theta);
  }
  const BoxObjective objective = [&](const std::vector<double>& theta, std::vector<double>& gradient) {
    try {
      return gp_log_marginal_likelihood(models, hyperparameters_from(theta, start), &gradient);
    } catch (const GpNotPositiveDefinite&) {  // K~ not positive definite there: a step to back off from
      gradient.assign(3, 0.0);
      return -static_cast<double>(INFINITY);
    }
  };
  return hyperparameters_from(maximise_in_box(objective, box, starts, options.max_iterations), start);
}

}  // namespace bgkmap
