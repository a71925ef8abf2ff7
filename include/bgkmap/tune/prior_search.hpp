// BGK-L's prior chosen on one build's kernel sums (prior_sums.hpp), without rebuilding: an NLopt
// search (unit_cube_search.hpp) of alpha0 and beta0, each on a log scale across its range.
#pragma once

#include <cstddef>

#include "bgkmap/core/params.hpp"
#include "bgkmap/tune/objective.hpp"
#include "bgkmap/tune/prior_sums.hpp"
#include "bgkmap/tune/tunable.hpp"

namespace bgkmap::tune {

// The prior, as the floats a map stores, that minimises the objective of the held-out scores
// under sigma0, starting from `start`. Ranges must be positive.
PriorParams best_prior(const HeldOutSums& sums, float sigma0, const PriorParams& start, const Range& alpha_range,
                       const Range& beta_range, Objective objective, size_t evaluations = 60);

}  // namespace bgkmap::tune
