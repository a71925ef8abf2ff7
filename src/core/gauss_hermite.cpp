#include "core/gauss_hermite.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace bgkmap {

// The roots of the n-th Hermite polynomial by Newton's method on the orthonormal recurrence
//   h_0 = pi^-1/4, h_1 = sqrt(2) x h_0, h_k = sqrt(2/k) x h_{k-1} - sqrt((k-1)/k) h_{k-2},
// whose derivative is h_n' = sqrt(2n) h_{n-1}; the weight of a root is 2 / h_n'(x)^2. The roots are
// symmetric: the largest are found first, each from a start below the previous one (the
// asymptotic spacing of the roots), the rest mirrored.
GaussHermite::GaussHermite(int n) {
  if (n < 1 || n > 100) throw std::invalid_argument("Gauss-Hermite: n must be in [1, 100], not " + std::to_string(n));
  nodes_.assign(n, 0.0);
  weights_.assign(n, 0.0);
  const double pi_quarter = 0.7511255444649425;  // pi^-1/4
  double x = 0;
  const int half = (n + 1) / 2;
  for (int i = 0; i < half; ++i) {
    if (i == 0) x = std::sqrt(2.0 * n + 1) - 1.85575 * std::pow(2.0 * n + 1, -1.0 / 6);
    else if (i == 1) x -= 1.14 * std::pow(static_cast<double>(n), 0.426) / x;
    else if (i == 2) x = 1.86 * x - 0.86 * nodes_[n - 1];
    else if (i == 3) x = 1.91 * x - 0.91 * nodes_[n - 2];
    else x = 2.0 * x - nodes_[n - i + 1];
    double derivative = 0;
    for (int iteration = 0; iteration < 100; ++iteration) {
      double h_prev = 0, h = pi_quarter;
      for (int k = 1; k <= n; ++k) {
        const double next = std::sqrt(2.0 / k) * x * h - std::sqrt((k - 1.0) / k) * h_prev;
        h_prev = h;
        h = next;
      }
      derivative = std::sqrt(2.0 * n) * h_prev;
      const double step = h / derivative;
      x -= step;
      if (std::abs(step) <= 1e-15 * std::max(1.0, std::abs(x))) break;
    }
    nodes_[n - 1 - i] = x;
    nodes_[i] = -x;
    weights_[n - 1 - i] = weights_[i] = 2.0 / (derivative * derivative);
  }
  if (n % 2 == 1) nodes_[n / 2] = 0.0;
}

}  // namespace bgkmap
