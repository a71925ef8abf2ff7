#include "methods/gp/plsc.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

namespace bgkmap {

namespace {

constexpr double kSqrt2 = 1.4142135623730951, kInvSqrt2Pi = 0.3989422804014327;

// log Phi(z) and N(z) / Phi(z), stable far into the lower tail (erfc keeps its relative precision).
double log_phi(double z) { return std::log(std::max(0.5 * std::erfc(-z / kSqrt2), 1e-300)); }
double phi_ratio(double z) { return std::exp(-0.5 * z * z - log_phi(z)) * kInvSqrt2Pi; }

}  // namespace

double plsc_probability(double mean, double variance, const PlscParams& plsc) {
  const double z = (plsc.alpha * mean + plsc.beta) / std::sqrt(1 + plsc.alpha * plsc.alpha * variance);
  return 0.5 * std::erfc(-z / kSqrt2);
}

double plsc_log_likelihood(const std::vector<LooSample>& samples, const PlscParams& plsc, double* d_alpha,
                           double* d_beta, int threads) {
  // Partial sums over fixed chunks, added in chunk order: the same bits for any thread count.
  constexpr size_t kChunk = 4096;
  const int64_t chunks = static_cast<int64_t>((samples.size() + kChunk - 1) / kChunk);
  std::vector<std::array<double, 3>> partial(static_cast<size_t>(chunks));
  const double a = plsc.alpha, b = plsc.beta;
#pragma omp parallel for schedule(static) num_threads(threads > 0 ? threads : omp_get_max_threads())
  for (int64_t c = 0; c < chunks; ++c) {
    double sum = 0, ga = 0, gb = 0;
    const size_t end = std::min(samples.size(), static_cast<size_t>(c + 1) * kChunk);
    for (size_t i = static_cast<size_t>(c) * kChunk; i < end; ++i) {
      const LooSample& s = samples[i];
      const double root = std::sqrt(1 + a * a * s.variance), u = a * s.mean + b;
      const double z = s.label * u / root;
      sum += log_phi(z);
      const double r = phi_ratio(z);
      // dz/dalpha = y (mu / root - u a s2 / root^3), dz/dbeta = y / root.
      ga += r * s.label * (s.mean / root - u * a * s.variance / (root * root * root));
      gb += r * s.label / root;
    }
    partial[static_cast<size_t>(c)] = {sum, ga, gb};
  }
  double sum = 0, ga = 0, gb = 0;
  for (const auto& p : partial) sum += p[0], ga += p[1], gb += p[2];
  if (d_alpha) *d_alpha = ga;
  if (d_beta) *d_beta = gb;
  return sum;
}

PlscParams fit_plsc(const std::vector<LooSample>& samples, PlscParams start, int threads) {
  if (samples.empty()) return start;
  const double n = static_cast<double>(samples.size());
  // Newton ascent in (log alpha, beta): alpha stays positive, so a larger mean stays more
  // occupied. The gradient is analytic, the Hessian its central difference.
  const auto params_at = [](double la, double b) { return PlscParams{std::exp(la), b}; };
  const auto gradient = [&](double la, double b, double g[2]) {
    double da = 0, db = 0;
    const double value = plsc_log_likelihood(samples, params_at(la, b), &da, &db, threads);
    g[0] = da * std::exp(la) / n;
    g[1] = db / n;
    return value / n;
  };
  double x[2] = {std::log(std::max(start.alpha, 1e-6)), start.beta}, g[2];
  double value = gradient(x[0], x[1], g);
  for (int iteration = 0; iteration < 200 && std::hypot(g[0], g[1]) > 1e-12; ++iteration) {
    const double h = 1e-5;
    double ga[2], gb[2], gc[2], gd[2];
    gradient(x[0] + h, x[1], ga);
    gradient(x[0] - h, x[1], gb);
    gradient(x[0], x[1] + h, gc);
    gradient(x[0], x[1] - h, gd);
    const double haa = (ga[0] - gb[0]) / (2 * h), hbb = (gc[1] - gd[1]) / (2 * h);
    const double hab = 0.5 * ((ga[1] - gb[1]) / (2 * h) + (gc[0] - gd[0]) / (2 * h));
    const double det = haa * hbb - hab * hab;
    double d[2] = {g[0], g[1]};  // steepest ascent where the Hessian is not negative definite
    const bool newton = haa < 0 && det > 0;
    if (newton) {
      d[0] = -(hbb * g[0] - hab * g[1]) / det, d[1] = -(-hab * g[0] + haa * g[1]) / det;
      // The Newton step's predicted gain is below the likelihood's rounding: the maximum is reached.
      if (0.5 * (g[0] * d[0] + g[1] * d[1]) <= 1e-15 * std::max(1.0, std::abs(value))) break;
    }
    bool improved = false;
    const double from[2] = {x[0], x[1]};
    const auto try_step = [&](double step) {
      double gy[2];
      const double y[2] = {from[0] + step * d[0], from[1] + step * d[1]};
      const double candidate = gradient(y[0], y[1], gy);
      if (!(candidate > value)) return false;
      x[0] = y[0], x[1] = y[1], value = candidate, g[0] = gy[0], g[1] = gy[1];
      return true;
    };
    for (double step = 1; step > 1e-12 && !improved; step *= 0.5) improved = try_step(step);
    // Where the surface is not concave the gradient's length says nothing about the distance to go:
    // a step that rose is doubled while the likelihood keeps rising, rather than many unit steps.
    if (improved && !newton)
      for (double step = 2; step < 1e6 && try_step(step); step *= 2) {
      }
    if (!improved) break;
  }
  return params_at(x[0], x[1]);
}

}  // namespace bgkmap
