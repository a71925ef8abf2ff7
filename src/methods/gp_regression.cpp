#include "methods/gp_regression.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "methods/gp_cholesky.hpp"
#include <cmath>
#include <stdexcept>

namespace bgkmap {

double gp_kernel(double d, const GpHyperParams& hp) {
  if (hp.covariance == GpCovariance::kMatern32) {
    const double r = 1.7320508075688772 * d / hp.ell_m;
    return hp.signal_var * (1 + r) * std::exp(-r);
  }
  if (d >= hp.ell_m) return 0;
  const double two_pi = 6.283185307179586, x = d / hp.ell_m;
  return hp.signal_var * ((2 + std::cos(two_pi * x)) / 3 * (1 - x) + std::sin(two_pi * x) / two_pi);
}

namespace {

// k(d) of every distance in `d`, in place. Matern's exp runs on Eigen's vectorised exp: the kernel
// matrix is a large share of a local model's cost, and each of its exps is separate.
void kernel_of_distances(Eigen::ArrayXd& d, const GpHyperParams& hp) {
  if (hp.covariance == GpCovariance::kMatern32) {
    const Eigen::ArrayXd r = d * (1.7320508075688772 / hp.ell_m);
    d = hp.signal_var * (1 + r) * (-r).exp();
    return;
  }
  for (Eigen::Index i = 0; i < d.size(); ++i) d[i] = gp_kernel(d[i], hp);
}

double distance(const Vec3d& a, const Vec3d& b) {
  const double dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

}  // namespace

Eigen::LLT<Eigen::MatrixXd> gp_factor(const std::vector<Vec3d>& train, const GpHyperParams& hp) {
  const Eigen::Index n = static_cast<Eigen::Index>(train.size());
  // The lower triangle's distances packed by rows, their kernel values at once, then unpacked.
  Eigen::ArrayXd packed(n * (n + 1) / 2);
  for (Eigen::Index i = 0, at = 0; i < n; ++i)
    for (Eigen::Index j = 0; j <= i; ++j) packed[at++] = distance(train[i], train[j]);
  kernel_of_distances(packed, hp);
  Eigen::MatrixXd k(n, n);
  for (Eigen::Index i = 0, at = 0; i < n; ++i)
    for (Eigen::Index j = 0; j <= i; ++j) k(i, j) = k(j, i) = packed[at++];
  k.diagonal().array() += hp.noise_std * hp.noise_std;
  Eigen::LLT<Eigen::MatrixXd> llt(k);
  if (llt.info() != Eigen::Success) throw std::runtime_error("GP: the kernel matrix is not positive definite");
  return llt;
}

std::vector<GpPrediction> gp_leave_one_out(const std::vector<Vec3d>& train, const std::vector<double>& labels,
                                           const GpHyperParams& hp) {
  const Eigen::Index n = static_cast<Eigen::Index>(train.size());
  const Eigen::LLT<Eigen::MatrixXd> llt = gp_factor(train, hp);
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
                                     const std::vector<Vec3d>& test, const GpHyperParams& hp) {
  const Eigen::Index n = static_cast<Eigen::Index>(train.size());
  const Eigen::LLT<Eigen::MatrixXd> llt = gp_factor(train, hp);
  const Eigen::VectorXd y = Eigen::Map<const Eigen::VectorXd>(labels.data(), n);
  const Eigen::VectorXd weights = llt.solve(y);

  std::vector<GpPrediction> out(test.size());
  Eigen::ArrayXd distances(n);
  for (size_t t = 0; t < test.size(); ++t) {
    for (Eigen::Index i = 0; i < n; ++i) distances[i] = distance(test[t], train[i]);
    kernel_of_distances(distances, hp);
    const Eigen::VectorXd k_star = distances.matrix();
    const Eigen::VectorXd v = llt.matrixL().solve(k_star);
    out[t].mean = k_star.dot(weights);
    out[t].variance = gp_kernel(0, hp) - v.squaredNorm();
    out[t].observed = (k_star.array() != 0.0).any();
  }
  return out;
}

double BcmCell::probability(double squash) const { return 1.0 / (1.0 + std::exp(-squash * weighted_mean)); }

}  // namespace bgkmap
