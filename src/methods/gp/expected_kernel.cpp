#include "methods/gp/expected_kernel.hpp"

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/gauss_hermite.hpp"
#include "core/gp_kernel_math.h"

namespace bgkmap {

namespace {

// E[k(|u|)], u ~ N(m, S), with the nodes where the integrand's mass is. With V = v I a Gaussian as
// wide as the kernel, N(u; m, S) N(u; 0, V) = N(m; 0, A) N(u; mu, P), A = S + V, mu = v A^-1 m,
// P = v I - v^2 A^-1, so
//   E[k] = N(m; 0, A) E_{u ~ N(mu, P)}[k(|u|) / N(u; 0, V)]
// by the product rule over N(mu, P) (nodes mu + sqrt(2) R x, R R^T = P). A small S gives P ~ S and
// mu ~ m (plain Gauss-Hermite over N(m, S)); a wide S gives P ~ V around the kernel, where plain
// nodes over N(m, S) would step over it. A and V are full rank, so a singular S is fine.
template <int D>
double matched_quadrature(const Vec3d& m3, const Eigen::Matrix3d& c, double v, const std::vector<double>& node_z,
                          const std::vector<double>& node_w, const GpHyperParams& hp) {
  using Mat = Eigen::Matrix<double, D, D>;
  using Vec = Eigen::Matrix<double, D, 1>;
  const Mat a = c.topLeftCorner<D, D>() + v * Mat::Identity();
  const Mat a_inv = a.inverse();
  const Vec m = Eigen::Vector3d(m3.x, m3.y, m3.z).head<D>();
  const Vec mu = v * (a_inv * m);
  Eigen::SelfAdjointEigenSolver<Mat> eig;
  eig.computeDirect(v * Mat::Identity() - v * v * a_inv);
  const Mat root = eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
  // N(m; 0, A) (2 pi v)^(D/2) = v^(D/2) / sqrt|A| exp(-1/2 m^T A^-1 m); the exponents are summed per node.
  const double scale = std::pow(v, 0.5 * D) / std::sqrt(a.determinant()), m_term = -0.5 * m.dot(a_inv * m);
  const double z2 = D == 2 ? m3.z * m3.z : 0.0;  // a planar map: the difference's z is not integrated
  double sum = 0;
  const size_t nodes = node_w.size();
  // The shared kernel inlined, not gp_kernel through the library's PLT: 64-216 calls a pair.
  const int covariance = static_cast<int>(hp.covariance);
  for (size_t n = 0; n < nodes; ++n) {
    const Vec u = mu + root * Eigen::Map<const Vec>(&node_z[n * D]);
    const double u2 = u.squaredNorm();
    sum += node_w[n] * gp_kernel_value(covariance, std::sqrt(u2 + z2), hp.ell_m, hp.signal_var) *
           std::exp(0.5 * u2 / v + m_term);
  }
  return scale * sum;
}

}  // namespace

ExpectedKernel::ExpectedKernel(const GpHyperParams& hp, int dims, int order) : hp_(hp), dims_(dims), order_(order) {
  if (dims != 2 && dims != 3) throw std::invalid_argument("expected kernel: dims must be 2 or 3");
  if (hp.covariance == GpCovariance::kNeuralNetwork)
    throw std::invalid_argument("expected kernel: the neural-network covariance is not a function of the distance");
  // The variance of a Gaussian about as wide as the kernel (measured: docs/ALGORITHM.md).
  kernel_variance_ = hp.ell_m * hp.ell_m * (hp.covariance == GpCovariance::kSparse ? 1.0 / 3 : 0.5);
  const GaussHermite rule(order);
  const double inv_sqrt_pi = 0.5641895835477563;
  int nodes = 1;
  for (int d = 0; d < dims; ++d) nodes *= order;
  for (int n = 0; n < nodes; ++n) {
    double w = 1;
    for (int d = 0, rest = n; d < dims; ++d, rest /= order) {
      node_z_.push_back(std::sqrt(2.0) * rule.nodes()[rest % order]);
      w *= rule.weights()[rest % order] * inv_sqrt_pi;
    }
    node_w_.push_back(w);
  }
}

double ExpectedKernel::operator()(const Vec3d& m, const PositionCovariance& s) const {
  if (s.is_zero()) return gp_kernel(std::sqrt(m.x * m.x + m.y * m.y + m.z * m.z), hp_);
  Eigen::Matrix3d c;
  c << s.xx, s.xy, s.xz, s.xy, s.yy, s.yz, s.xz, s.yz, s.zz;
  const Eigen::Vector3d mean(m.x, m.y, m.z);
  if (hp_.covariance == GpCovariance::kSquaredExponential) {
    const double l2 = hp_.ell_m * hp_.ell_m;
    const Eigen::Matrix3d a = l2 * Eigen::Matrix3d::Identity() + c;
    // |I + S / l^2| = |l^2 I + S| / l^6.
    const double det = a.determinant() / (l2 * l2 * l2);
    return hp_.signal_var / std::sqrt(det) * std::exp(-0.5 * mean.dot(a.ldlt().solve(mean)));
  }
  return dims_ == 2 ? matched_quadrature<2>(m, c, kernel_variance_, node_z_, node_w_, hp_)
                    : matched_quadrature<3>(m, c, kernel_variance_, node_z_, node_w_, hp_);
}

}  // namespace bgkmap
