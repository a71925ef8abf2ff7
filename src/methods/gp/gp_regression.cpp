#include "methods/gp/gp_regression.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include <cmath>
#include <stdexcept>

#include "core/gp_kernel_math.h"
#include "methods/gp/expected_kernel.hpp"
#include "methods/gp/gp_cholesky.hpp"

namespace bgkmap {

double gp_kernel(double d, const GpHyperParams& hp) {
  if (hp.covariance == GpCovariance::kNeuralNetwork)
    throw std::invalid_argument("GP: the neural-network covariance is a function of two inputs (gp_covariance)");
  return gp_kernel_value(static_cast<int>(hp.covariance), d, hp.ell_m, hp.signal_var);
}

namespace {

double distance(const Vec3d& a, const Vec3d& b) {
  const double dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

Vec3d difference(const Vec3d& a, const Vec3d& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }

// gp_covariance, inlined here: called once per pair of a local model, and gp_covariance itself
// goes through the shared library's PLT.
double covariance(const Vec3d& a, const Vec3d& b, const GpHyperParams& hp) {
  if (hp.covariance != GpCovariance::kNeuralNetwork)
    return gp_kernel_value(static_cast<int>(hp.covariance), distance(a, b), hp.ell_m, hp.signal_var);
  // By Cauchy-Schwarz |2 a~^T S b~| < sqrt((1 + 2 a~^T S a~)(1 + 2 b~^T S b~)): the asin's argument
  // is inside (-1, 1).
  const NeuralNetworkTerms t = neural_network_terms(a, b, hp);
  return hp.signal_var * 0.6366197723675814 * std::asin(2 * t.ab / std::sqrt((1 + 2 * t.aa) * (1 + 2 * t.bb)));
}

// Training input i's covariance with the certain point q.
double train_test_covariance(const std::vector<Vec3d>& train, size_t i, const Vec3d& q, const GpHyperParams& hp,
                             const InputUncertainty* uncertain) {
  if (!uncertain) return covariance(q, train[i], hp);
  return (*uncertain->kernel)(difference(train[i], q), (*uncertain->covariances)[i]);
}

}  // namespace

double gp_covariance(const Vec3d& a, const Vec3d& b, const GpHyperParams& hp) { return covariance(a, b, hp); }

Eigen::LLT<Eigen::MatrixXd> gp_factor(const std::vector<Vec3d>& train, const GpHyperParams& hp,
                                      const InputUncertainty* uncertain) {
  const Eigen::Index n = static_cast<Eigen::Index>(train.size());
  Eigen::MatrixXd k(n, n);
  if (uncertain && uncertain->covariances->size() != train.size())
    throw std::invalid_argument("GP: one input covariance per training input");
  if (uncertain && uncertain->pair_covariances && uncertain->pair_covariances->size() != train.size() * train.size())
    throw std::invalid_argument("GP: one difference covariance per pair of training inputs");
  if (!uncertain) {
    for (Eigen::Index i = 0; i < n; ++i)
      for (Eigen::Index j = 0; j <= i; ++j) k(i, j) = k(j, i) = covariance(train[i], train[j], hp);
  } else {
    const std::vector<PositionCovariance>& s = *uncertain->covariances;
    const std::vector<PositionCovariance>* pairs = uncertain->pair_covariances;
    for (Eigen::Index i = 0; i < n; ++i)
      for (Eigen::Index j = 0; j <= i; ++j)
        k(i, j) = k(j, i) = i == j ? covariance(train[i], train[i], hp)
                                   : (*uncertain->kernel)(difference(train[i], train[j]),
                                                          pairs ? (*pairs)[size_t(i * n + j)] : s[i] + s[j]);
  }
  k.diagonal().array() += hp.noise_std * hp.noise_std;
  Eigen::LLT<Eigen::MatrixXd> llt(k);
  if (llt.info() != Eigen::Success) throw GpNotPositiveDefinite();
  return llt;
}

std::vector<GpPrediction> gp_leave_one_out(const std::vector<Vec3d>& train, const std::vector<double>& labels,
                                           const GpHyperParams& hp, const InputUncertainty* uncertain) {
  const Eigen::Index n = static_cast<Eigen::Index>(train.size());
  const Eigen::LLT<Eigen::MatrixXd> llt = gp_factor(train, hp, uncertain);
  const Eigen::MatrixXd inverse = llt.solve(Eigen::MatrixXd::Identity(n, n));
  const Eigen::VectorXd weights = inverse * Eigen::Map<const Eigen::VectorXd>(labels.data(), n);
  std::vector<GpPrediction> out(train.size());
  for (Eigen::Index i = 0; i < n; ++i) {
    out[i].variance = 1.0 / inverse(i, i);
    out[i].mean = labels[i] - weights(i) * out[i].variance;
    out[i].observed = true;
  }
  return out;
}

std::vector<GpPrediction> gp_predict(const std::vector<Vec3d>& train, const std::vector<double>& labels,
                                     const std::vector<Vec3d>& test, const GpHyperParams& hp,
                                     const InputUncertainty* uncertain) {
  const Eigen::Index n = static_cast<Eigen::Index>(train.size());
  const Eigen::LLT<Eigen::MatrixXd> llt = gp_factor(train, hp, uncertain);
  const Eigen::VectorXd y = Eigen::Map<const Eigen::VectorXd>(labels.data(), n);
  const Eigen::VectorXd weights = llt.solve(y);

  std::vector<GpPrediction> out(test.size());
  Eigen::VectorXd k_star(n);
  for (size_t t = 0; t < test.size(); ++t) {
    for (Eigen::Index i = 0; i < n; ++i) k_star(i) = train_test_covariance(train, size_t(i), test[t], hp, uncertain);
    const Eigen::VectorXd v = llt.matrixL().solve(k_star);
    out[t].mean = k_star.dot(weights);
    out[t].variance = covariance(test[t], test[t], hp) - v.squaredNorm();
    out[t].observed = (k_star.array() != 0.0).any();
  }
  return out;
}

double BcmCell::probability(double squash) const { return 1.0 / (1.0 + std::exp(-squash * weighted_mean)); }

}  // namespace bgkmap
