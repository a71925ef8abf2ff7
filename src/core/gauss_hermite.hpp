// Gauss-Hermite quadrature: expectations over a Gaussian as weighted sums of the integrand at a
// few nodes, exact for polynomials of degree < 2n. WGPOM's predictive mean in observation space
// (the inverse warp's expectation over the latent Gaussian) uses it; so can expected kernels.
#pragma once

#include <cmath>
#include <vector>

namespace bgkmap {

class GaussHermite {
 public:
  // The n-point rule (1 <= n <= 100): nodes x_i and weights w_i with
  //   integral f(x) exp(-x^2) dx ~ sum_i w_i f(x_i), nodes ascending.
  explicit GaussHermite(int n);

  const std::vector<double>& nodes() const { return nodes_; }
  const std::vector<double>& weights() const { return weights_; }
  int size() const { return static_cast<int>(nodes_.size()); }

  // E[f(z)] for z ~ N(mean, variance): sum_i w_i / sqrt(pi) f(mean + sqrt(2 variance) x_i).
  template <class F>
  double expectation(double mean, double variance, F&& f) const;

 private:
  std::vector<double> nodes_, weights_;
};

template <class F>
double GaussHermite::expectation(double mean, double variance, F&& f) const {
  const double scale = variance > 0 ? std::sqrt(2 * variance) : 0.0;
  double sum = 0;
  for (size_t i = 0; i < nodes_.size(); ++i) sum += weights_[i] * f(mean + scale * nodes_[i]);
  return sum * 0.5641895835477563;  // 1 / sqrt(pi)
}

}  // namespace bgkmap
