#include "bgkmap/map/expected_submap.hpp"

#include <algorithm>
#include <cstdint>
#include <stdexcept>

namespace bgkmap {

namespace {
struct Moments {
  double mean = 0, var = 0;
};
Moments beta_moments(double a, double b) {
  const CellPosterior beta{a, b};
  return {beta.mean(), beta.variance()};
}

// Beta(m nu, (1 - m) nu) has variance m (1 - m) / (nu + 1). The mixture's variance is the mean
// of its components' variances plus the variance of their means (the latter clamped at 0: it is
// a difference of sums and may round below).
BetaParams beta_of(double mean, double mean_sq, double var) {
  const double total_var = var + std::max(0.0, mean_sq - mean * mean);
  const double nu = mean * (1.0 - mean) / total_var - 1.0;
  return {mean * nu, (1.0 - mean) * nu};
}
}  // namespace

BetaParams moment_matched_beta(const std::vector<BetaParams>& components, const std::vector<double>& weights) {
  if (components.size() != weights.size() || components.empty())
    throw std::invalid_argument("moment_matched_beta: one weight per component, at least one");
  double mean = 0, mean_sq = 0, var = 0;
  for (size_t h = 0; h < components.size(); ++h) {
    const Moments m = beta_moments(components[h].alpha, components[h].beta);
    mean += weights[h] * m.mean;
    mean_sq += weights[h] * m.mean * m.mean;
    var += weights[h] * m.var;
  }
  return beta_of(mean, mean_sq, var);
}

void ExpectedSubmap::clear() {
  block_of_slot_.clear();
  slots_.clear();
  weight_.clear();
}

void ExpectedSubmap::start_hypothesis(BgkMap& map, const std::vector<uint32_t>& slots) {
  const size_t n = static_cast<size_t>(map.cells_per_block());
  if (slots_.empty()) cells_per_block_ = n;
  const Cell prior{map.params().prior.alpha0, map.params().prior.beta0};
  for (const uint32_t slot : slots) {
    Cell* cells = map.block_cells(slot);
    const auto [it, added] = block_of_slot_.try_emplace(slot, static_cast<uint32_t>(slots_.size()));
    if (added) {
      slots_.push_back(slot);
      weight_.push_back(0.0);
      const size_t cells_before = (slots_.size() - 1) * n, cells_after = slots_.size() * n;
      // resize keeps the capacity of earlier scans; the new block's sums start at 0.
      before_.resize(cells_after);
      std::copy(cells, cells + n, before_.begin() + cells_before);
      for (std::vector<double>* sums : {&mean_, &mean_sq_, &var_}) {
        sums->resize(cells_after);
        std::fill(sums->begin() + cells_before, sums->end(), 0.0);
      }
      changed_.resize(cells_after);
      std::fill(changed_.begin() + cells_before, changed_.end(), 0);
    }
    std::fill(cells, cells + n, prior);
  }
}

void ExpectedSubmap::add_hypothesis(const BgkMap& map, const std::vector<uint32_t>& slots, double weight, int threads) {
  const Cell prior{map.params().prior.alpha0, map.params().prior.beta0};
  blocks_.clear();
  for (const uint32_t slot : slots) {
    const auto it = block_of_slot_.find(slot);
    if (it == block_of_slot_.end()) throw std::logic_error("ExpectedSubmap: a hypothesis' block was not started");
    blocks_.push_back(it->second);
  }
  const size_t n = cells_per_block_;
#pragma omp parallel for schedule(static) num_threads(std::max(threads, 1))
  for (int64_t k = 0; k < static_cast<int64_t>(slots.size()); ++k) {
    const size_t first = blocks_[k] * n;
    const Cell* cells = map.block_cells(slots[k]);
    for (size_t i = 0; i < n; ++i) {
      const Moments m = beta_moments(cells[i].alpha, cells[i].beta);
      mean_[first + i] += weight * m.mean;
      mean_sq_[first + i] += weight * m.mean * m.mean;
      var_[first + i] += weight * m.var;
      if (cells[i].alpha != prior.alpha || cells[i].beta != prior.beta) changed_[first + i] = 1;
    }
    weight_[blocks_[k]] += weight;
  }
}

void ExpectedSubmap::add_to_map(BgkMap& map, int threads) const {
  const double alpha0 = map.params().prior.alpha0, beta0 = map.params().prior.beta0;
  const Moments m0 = beta_moments(alpha0, beta0);
  const size_t n = cells_per_block_;
#pragma omp parallel for schedule(static) num_threads(std::max(threads, 1))
  for (int64_t k = 0; k < static_cast<int64_t>(slots_.size()); ++k) {
    Cell* cells = map.block_cells(slots_[k]);
    const double rest = std::max(0.0, 1.0 - weight_[k]);  // hypotheses that never reached the block
    for (size_t i = 0; i < n; ++i) {
      const size_t c = k * n + i;
      if (!changed_[c]) {
        cells[i] = before_[c];
        continue;
      }
      const BetaParams s = beta_of(mean_[c] + rest * m0.mean, mean_sq_[c] + rest * m0.mean * m0.mean,
                                   var_[c] + rest * m0.var);
      // The matched Beta may be weaker than the prior in one count (a cell most hypotheses never
      // see): the scan then adds nothing to that count rather than taking evidence away.
      cells[i].alpha = static_cast<float>(before_[c].alpha + std::max(0.0, s.alpha - alpha0));
      cells[i].beta = static_cast<float>(before_[c].beta + std::max(0.0, s.beta - beta0));
    }
  }
}

}  // namespace bgkmap
