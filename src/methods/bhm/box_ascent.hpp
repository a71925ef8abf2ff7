// The maximum of a smooth function of a few parameters within a box, from several starts: how
// wgpom learns its warp and gpom/wgpom their covariance's hyper-parameters (marginal
// likelihoods). Internal header of the methods (tests include it).
#pragma once

#include <functional>
#include <vector>

namespace bgkmap {

// The value at theta and, in `gradient`, its gradient with respect to theta.
using BoxObjective = std::function<double(const std::vector<double>& theta, std::vector<double>& gradient)>;

struct Box {
  std::vector<double> lo, hi;  // per parameter, lo < hi
};

// BFGS ascent (Armijo backtracking) from each start in variables x with theta = lo + (hi - lo)
// logistic(x), so every step stays inside the box; the best end is returned (with its value in
// *best_value where asked). Starts are clamped into the box.
std::vector<double> maximise_in_box(const BoxObjective& f, const Box& box, const std::vector<std::vector<double>>& starts,
                                    int max_iterations, double* best_value = nullptr);

}  // namespace bgkmap
