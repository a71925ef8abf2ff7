// The tests' reference GP: the exact posterior by Gauss-Jordan elimination on the full system
// (no Cholesky, no Eigen), for the GP methods' tests (test_gpom, test_expected_kernel).
#pragma once

#include <cmath>
#include <utility>
#include <vector>

#include "bgkmap/methods/method.hpp"
#include "methods/gp/gp_regression.hpp"

namespace bgkmap::testing {

// The dense references' GP settings: l = 0.3 m, s2 = 1, sn = 0.1, and local models larger than
// testing::two_planar_scans' data (every hit and beam in every local model).
inline MethodParams dense_reference_method_params() {
  MethodParams mp;
  mp.set("gp-length", 0.3);
  mp.set("gp-signal", 1.0);
  mp.set("gp-noise", 0.1);
  mp.set("gp-neighbours", 100);
  return mp;
}

// Given the kernel matrix k (noise included on its diagonal), the test covariances ks and k(x*, x*):
// mean ks^T k^-1 y and variance kss - ks^T k^-1 ks.
inline GpPrediction dense_gp(const std::vector<std::vector<double>>& k, const std::vector<double>& ks, double kss,
                             const std::vector<double>& y) {
  const size_t n = y.size();
  // [K | y | k*]: both right-hand sides at once.
  std::vector<std::vector<double>> m(n, std::vector<double>(n + 2));
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = 0; j < n; ++j) m[i][j] = k[i][j];
    m[i][n] = y[i];
    m[i][n + 1] = ks[i];
  }
  for (size_t c = 0; c < n; ++c) {
    size_t pivot = c;
    for (size_t r = c + 1; r < n; ++r)
      if (std::abs(m[r][c]) > std::abs(m[pivot][c])) pivot = r;
    std::swap(m[c], m[pivot]);
    for (size_t r = 0; r < n; ++r) {
      if (r == c) continue;
      const double f = m[r][c] / m[c][c];
      for (size_t q = c; q < n + 2; ++q) m[r][q] -= f * m[c][q];
    }
  }
  GpPrediction p;
  p.variance = kss;
  for (size_t i = 0; i < n; ++i) {
    p.mean += ks[i] * m[i][n] / m[i][i];
    p.variance -= ks[i] * m[i][n + 1] / m[i][i];
  }
  return p;
}

}  // namespace bgkmap::testing
