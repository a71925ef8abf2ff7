#include "bgkmap/map/expected_submap.hpp"

#include <algorithm>
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

void ExpectedSubmap::clear() { blocks_.clear(); }

std::vector<uint32_t> ExpectedSubmap::slots() const {
  std::vector<uint32_t> out;
  out.reserve(blocks_.size());
  for (const auto& block : blocks_) out.push_back(block.first);
  return out;
}

void ExpectedSubmap::start_hypothesis(BgkMap& map, const std::vector<uint32_t>& slots) {
  const size_t n = static_cast<size_t>(map.cells_per_block());
  const Cell prior{map.params().prior.alpha0, map.params().prior.beta0};
  for (const uint32_t slot : slots) {
    Cell* cells = map.block_cells(slot);
    auto [it, added] = blocks_.try_emplace(slot);
    if (added) {
      Block& b = it->second;
      b.before.assign(cells, cells + n);
      b.mean.assign(n, 0.0);
      b.mean_sq.assign(n, 0.0);
      b.var.assign(n, 0.0);
      b.changed.assign(n, 0);
    }
    std::fill(cells, cells + n, prior);
  }
}

void ExpectedSubmap::add_hypothesis(BgkMap& map, const std::vector<uint32_t>& slots, double weight) {
  const Cell prior{map.params().prior.alpha0, map.params().prior.beta0};
  for (const uint32_t slot : slots) {
    const auto it = blocks_.find(slot);
    if (it == blocks_.end()) throw std::logic_error("ExpectedSubmap: a hypothesis' block was not started");
    Block& b = it->second;
    Cell* cells = map.block_cells(slot);
    for (size_t i = 0; i < b.before.size(); ++i) {
      const Moments m = beta_moments(cells[i].alpha, cells[i].beta);
      b.mean[i] += weight * m.mean;
      b.mean_sq[i] += weight * m.mean * m.mean;
      b.var[i] += weight * m.var;
      if (cells[i].alpha != prior.alpha || cells[i].beta != prior.beta) b.changed[i] = 1;
      cells[i] = b.before[i];
    }
    b.weight += weight;
  }
}

void ExpectedSubmap::add_to_map(BgkMap& map) const {
  const double alpha0 = map.params().prior.alpha0, beta0 = map.params().prior.beta0;
  const Moments m0 = beta_moments(alpha0, beta0);
  for (const auto& [slot, b] : blocks_) {
    Cell* cells = map.block_cells(slot);
    const double rest = std::max(0.0, 1.0 - b.weight);  // hypotheses that never reached the block
    for (size_t i = 0; i < b.before.size(); ++i) {
      if (!b.changed[i]) continue;
      const BetaParams s = beta_of(b.mean[i] + rest * m0.mean, b.mean_sq[i] + rest * m0.mean * m0.mean,
                                   b.var[i] + rest * m0.var);
      // The matched Beta may be weaker than the prior in one count (a cell most hypotheses never
      // see): the scan then adds nothing to that count rather than taking evidence away.
      cells[i].alpha = static_cast<float>(b.before[i].alpha + std::max(0.0, s.alpha - alpha0));
      cells[i].beta = static_cast<float>(b.before[i].beta + std::max(0.0, s.beta - beta0));
    }
  }
}

}  // namespace bgkmap
