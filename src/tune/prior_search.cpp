#include "bgkmap/tune/prior_search.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "bgkmap/eval/scored_map.hpp"
#include "bgkmap/tune/unit_cube_search.hpp"

namespace bgkmap::tune {

namespace {

// Samples with the same sums (the same cell, seen by several held-out beams) scored once.
struct SameSums {
  double hits = 0, free = 0, count = 0;
};

std::vector<SameSums> collapsed(std::vector<KernelSums> sums) {
  sums.erase(std::remove_if(sums.begin(), sums.end(), [](const KernelSums& s) { return !s.evidence; }), sums.end());
  std::sort(sums.begin(), sums.end(),
            [](const KernelSums& a, const KernelSums& b) { return a.hits < b.hits || (a.hits == b.hits && a.free < b.free); });
  std::vector<SameSums> out;
  for (const KernelSums& s : sums) {
    if (out.empty() || out.back().hits != s.hits || out.back().free != s.free) out.push_back({s.hits, s.free, 0});
    out.back().count += 1;
  }
  return out;
}

// eval::mean_nll of scores_from_sums, summed over the collapsed samples.
class CollapsedNll {
 public:
  explicit CollapsedNll(const HeldOutSums& sums)
      : occupied_(collapsed(sums.occupied)), free_(collapsed(sums.free)),
        total_(double(sums.occupied.size() + sums.free.size())) {
    double known = 0;
    for (const auto* group : {&occupied_, &free_})
      for (const SameSums& s : *group) known += s.count;
    unknown_ = total_ - known;
  }
  double operator()(double sigma0, double alpha0, double beta0) const {
    const auto clamp = [](double p) { return std::min(std::max(p, eval::kNllClamp), 1.0 - eval::kNllClamp); };
    double sum = -unknown_ * std::log(eval::kUnknownScore);
    for (const SameSums& s : occupied_) {
      const double a = alpha0 + sigma0 * s.hits, b = beta0 + sigma0 * s.free;
      sum -= s.count * std::log(clamp(a / (a + b)));
    }
    for (const SameSums& s : free_) {
      const double a = alpha0 + sigma0 * s.hits, b = beta0 + sigma0 * s.free;
      sum -= s.count * std::log(1.0 - clamp(a / (a + b)));
    }
    return sum / total_;
  }

 private:
  std::vector<SameSums> occupied_, free_;
  double total_ = 0, unknown_ = 0;
};

}  // namespace

PriorParams best_prior(const HeldOutSums& sums, float sigma0, const PriorParams& start, const Range& alpha_range,
                       const Range& beta_range, Objective objective, size_t evaluations) {
  const CollapsedNll nll(sums);
  const auto value = [&](const PriorParams& p) {
    return objective == Objective::kNll ? nll(sigma0, p.alpha0, p.beta0)
                                        : objective_value(scores_from_sums(sums, sigma0, p.alpha0, p.beta0), objective);
  };
  // Scored at the floats the map would store, so that the value found is the value built.
  const auto prior_at = [&](const std::vector<double>& u) {
    return PriorParams{static_cast<float>(from_unit(true, alpha_range, u[0])),
                       static_cast<float>(from_unit(true, beta_range, u[1]))};
  };
  const UnitObjective f = [&](const std::vector<double>& u, const std::string&) { return value(prior_at(u)); };
  SearchBudget budget;
  budget.evaluations = evaluations;
  const std::vector<double> u0 = {to_unit(true, alpha_range, start.alpha0), to_unit(true, beta_range, start.beta0)};
  const SearchResult best = minimise_in_unit_cube(f, u0, budget);
  // The start itself when nothing beat it (its unit coordinates may round to another float).
  return best.value < value(start) ? prior_at(best.best) : start;
}

}  // namespace bgkmap::tune
