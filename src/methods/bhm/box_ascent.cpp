#include "methods/bhm/box_ascent.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>

namespace bgkmap {

namespace {

double logistic(double s) { return 1 / (1 + std::exp(-s)); }

// Maximises f (value and gradient) from x by BFGS on the inverse Hessian with an Armijo
// backtracking line search; stops when no step improves f or the gradient vanishes.
double bfgs_ascent(const std::function<double(const std::vector<double>&, std::vector<double>&)>& f,
                   std::vector<double>& x, int max_iterations) {
  const size_t n = x.size();
  std::vector<double> g(n), g_new(n), d(n), x_new(n);
  double value = f(x, g);
  if (!std::isfinite(value)) return value;
  Eigen::MatrixXd h = Eigen::MatrixXd::Identity(n, n);  // inverse Hessian of -f
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    double g_norm = 0;
    for (const double gi : g) g_norm = std::max(g_norm, std::abs(gi));
    if (g_norm < 1e-9) break;
    for (size_t i = 0; i < n; ++i) {
      d[i] = 0;
      for (size_t k = 0; k < n; ++k) d[i] += h(i, k) * g[k];
    }
    double slope = 0;
    for (size_t i = 0; i < n; ++i) slope += g[i] * d[i];
    if (!(slope > 0)) {  // not an ascent direction: restart from steepest ascent
      h.setIdentity();
      d = g;
      slope = 0;
      for (const double gi : g) slope += gi * gi;
    }
    double step = 1, candidate = -INFINITY;
    for (int tries = 0; tries < 50; ++tries, step *= 0.5) {
      for (size_t i = 0; i < n; ++i) x_new[i] = x[i] + step * d[i];
      candidate = f(x_new, g_new);
      if (std::isfinite(candidate) && candidate >= value + 1e-4 * step * slope) break;
    }
    if (!(std::isfinite(candidate) && candidate > value)) break;
    Eigen::VectorXd s(n), y(n);
    for (size_t i = 0; i < n; ++i) s(i) = x_new[i] - x[i], y(i) = g[i] - g_new[i];  // y: change of -grad
    const double sy = s.dot(y);
    if (sy > 1e-12) {
      const Eigen::VectorXd hy = h * y;
      h += ((sy + y.dot(hy)) / (sy * sy)) * s * s.transpose() - (hy * s.transpose() + s * hy.transpose()) / sy;
    }
    const bool stalled = candidate - value <= 1e-13 * std::max(1.0, std::abs(value));
    x = x_new, g = g_new, value = candidate;
    if (stalled) break;
  }
  return value;
}

}  // namespace

std::vector<double> maximise_in_box(const BoxObjective& f, const Box& box, const std::vector<std::vector<double>>& starts,
                                    int max_iterations, double* best_value) {
  const size_t n = box.lo.size();
  const auto theta_of = [&](const std::vector<double>& x) {
    std::vector<double> theta(n);
    for (size_t k = 0; k < n; ++k) theta[k] = box.lo[k] + (box.hi[k] - box.lo[k]) * logistic(x[k]);
    return theta;
  };
  const auto objective = [&](const std::vector<double>& x, std::vector<double>& g) {
    const double value = f(theta_of(x), g);
    for (size_t k = 0; k < n; ++k) {
      const double p = logistic(x[k]);
      g[k] *= (box.hi[k] - box.lo[k]) * p * (1 - p);
    }
    return value;
  };
  std::vector<double> best_x;
  double best = -INFINITY;
  for (const std::vector<double>& start : starts) {
    std::vector<double> x(n);
    for (size_t k = 0; k < n; ++k) {
      const double p = std::clamp((start[k] - box.lo[k]) / (box.hi[k] - box.lo[k]), 1e-6, 1 - 1e-6);
      x[k] = std::log(p / (1 - p));
    }
    const double value = bfgs_ascent(objective, x, max_iterations);
    if (value > best || best_x.empty()) best = value, best_x = x;
  }
  if (best_value) *best_value = best;
  return best_x.empty() ? std::vector<double>{} : theta_of(best_x);
}

}  // namespace bgkmap
