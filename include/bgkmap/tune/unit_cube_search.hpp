// A bounded, derivative-free minimisation over the unit cube [0, 1]^n by NLopt: a global step
// (DIRECT-L, deterministic) on part of the budget, then a local one (BOBYQA) from the best point
// so far. The same objective and budget give the same points in the same order.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace bgkmap::tune {

// f(x, phase): the objective at x, phase "start", "global" or "local". Non-finite values count as
// the worst. Exceptions it throws end the search and propagate.
using UnitObjective = std::function<double(const std::vector<double>& x, const std::string& phase)>;

struct SearchBudget {
  size_t evaluations = 20;     // calls of f, the start included
  double seconds = 0;          // > 0: no call starts after this long
  double global_share = 0.5;   // of the evaluations after the start, for the global step
  double local_step = 0.1;     // BOBYQA's initial step in the cube
  double local_tolerance = 1e-4;  // BOBYQA stops when steps shrink below this (per coordinate)
};

struct SearchResult {
  std::vector<double> best;
  double value = 0;
  size_t evaluations = 0;
};

// Starts at `start` (clamped into the cube). Throws std::invalid_argument for an empty start.
SearchResult minimise_in_unit_cube(const UnitObjective& f, const std::vector<double>& start, const SearchBudget& budget);

}  // namespace bgkmap::tune
