#include "bgkmap/tune/prior_search.hpp"

#include <vector>

#include "bgkmap/tune/unit_cube_search.hpp"

namespace bgkmap::tune {

PriorParams best_prior(const HeldOutSums& sums, float sigma0, const PriorParams& start, const Range& alpha_range,
                       const Range& beta_range, Objective objective, size_t evaluations) {
  // Scored at the floats the map would store, so that the value found is the value built.
  const auto prior_at = [&](const std::vector<double>& u) {
    return PriorParams{static_cast<float>(from_unit(true, alpha_range, u[0])),
                       static_cast<float>(from_unit(true, beta_range, u[1]))};
  };
  const UnitObjective f = [&](const std::vector<double>& u, const std::string&) {
    const PriorParams p = prior_at(u);
    return objective_value(scores_from_sums(sums, sigma0, p.alpha0, p.beta0), objective);
  };
  SearchBudget budget;
  budget.evaluations = evaluations;
  const std::vector<double> u0 = {to_unit(true, alpha_range, start.alpha0), to_unit(true, beta_range, start.beta0)};
  const SearchResult best = minimise_in_unit_cube(f, u0, budget);
  // The start itself when nothing beat it (its unit coordinates may round to another float).
  const double at_start = objective_value(scores_from_sums(sums, sigma0, start.alpha0, start.beta0), objective);
  return best.value < at_start ? prior_at(best.best) : start;
}

}  // namespace bgkmap::tune
