// Probabilistic least-squares classification (Rasmussen & Williams sec. 6.5, GPOM's squashing):
// a GP regression's latent mean mu and variance s2 become P(occupied) = Phi((alpha mu + beta) /
// sqrt(1 + alpha^2 s2)), alpha and beta fitted by maximising the leave-one-out pseudo-likelihood
// of the training labels. Internal header of the gpom method (tests include it).
#pragma once

#include <vector>

namespace bgkmap {

// One training label and its leave-one-out prediction (gp_leave_one_out).
struct LooSample {
  double label = 0;  // +1 occupied, -1 free
  double mean = 0, variance = 0;
};

struct PlscParams {
  double alpha = 1, beta = 0;
};

// Phi((alpha mean + beta) / sqrt(1 + alpha^2 variance)): P(label = +1).
double plsc_probability(double mean, double variance, const PlscParams& plsc);

// sum_i log Phi(y_i (alpha mu_i + beta) / sqrt(1 + alpha^2 s2_i)) (R&W eq. 6.42) and, where
// asked, its gradient with respect to alpha and beta; on `threads` threads (0: OpenMP's default),
// the same bits for any number.
double plsc_log_likelihood(const std::vector<LooSample>& samples, const PlscParams& plsc, double* d_alpha = nullptr,
                           double* d_beta = nullptr, int threads = 0);

// alpha > 0 and beta maximising plsc_log_likelihood, from `start`: on log alpha and beta, Newton
// steps where the surface is concave and gradient steps (doubled while they keep rising)
// elsewhere, both backtracked, until no step improves it or Newton's predicted gain is below the
// likelihood's rounding. Returns `start` for no samples.
PlscParams fit_plsc(const std::vector<LooSample>& samples, PlscParams start = {}, int threads = 0);

}  // namespace bgkmap
