// The expected sub-map of a scan under pose uncertainty (docs/ALGORITHM.md, "Pose
// uncertainty"): under each pose hypothesis h (weight w_h) the scan alone would leave a cell at
// Beta(alpha0 + a_h, beta0 + b_h), its plain BGK-L counts a_h, b_h added to the prior. The scan's
// expected sub-map is the Beta with the mean and variance of that mixture (moment matching); its
// counts beyond the prior are what the scan adds to the map, as any scan's counts are added.
#pragma once

#include <cstdint>
#include <unordered_map>
#include <vector>

#include "bgkmap/map/bgk_map.hpp"

namespace bgkmap {

// A Beta distribution's parameters.
struct BetaParams {
  double alpha = 0, beta = 0;
};

// The Beta with the mean and variance of the mixture sum_h weights[h] Beta(components[h]); the
// weights must sum to 1. (A mixture's variance is below m (1 - m) unless every component is a
// point mass, so its alpha + beta is positive.)
BetaParams moment_matched_beta(const std::vector<BetaParams>& components, const std::vector<double>& weights);

// Collects a scan's cells under each pose hypothesis in turn, then adds the expected sub-map's
// counts to the map. Per scan: for each hypothesis, start_hypothesis, the hypothesis' plain
// update of those slots, add_hypothesis; then add_to_map. Its storage is kept from scan to scan
// (a scan remembers tens of thousands of blocks). `threads`: OpenMP threads over the blocks.
class ExpectedSubmap {
 public:
  // Forgets the previous scan.
  void clear();
  // Remembers the cells of `slots` (those not remembered yet) and sets every cell of `slots` to
  // the prior, for one hypothesis' plain update to add its counts to. Slots must not repeat.
  void start_hypothesis(BgkMap& map, const std::vector<uint32_t>& slots);
  // Takes the cells of `slots`, the same slots as start_hypothesis after the update, as the
  // hypothesis' sub-map with weight `weight` (reads the map only).
  void add_hypothesis(const BgkMap& map, const std::vector<uint32_t>& slots, double weight, int threads = 1);
  // Writes every cell of the remembered blocks without reading them: the remembered cell plus,
  // where some hypothesis changed it, the expected sub-map's counts beyond the prior (each
  // clamped at 0). Hypotheses that left a cell at the prior count as such; the weights added
  // must sum to 1. Cells no hypothesis changed get their remembered bits back.
  void add_to_map(BgkMap& map, int threads = 1) const;

  // The slots remembered since clear(): those add_to_map writes.
  const std::vector<uint32_t>& slots() const { return slots_; }

 private:
  // Remembered block k holds cells [k n, (k + 1) n) of the arrays (n cells per block).
  std::unordered_map<uint32_t, uint32_t> block_of_slot_;
  std::vector<uint32_t> slots_;  // per remembered block, its slot
  size_t cells_per_block_ = 0;
  std::vector<Cell> before_;
  // Per cell, summed over the hypotheses that touched its block: w_h m_h, w_h m_h^2, w_h v_h
  // (m_h, v_h the mean and variance of the cell's Beta under h).
  std::vector<double> mean_, mean_sq_, var_;
  std::vector<uint8_t> changed_;  // some hypothesis moved the cell away from the prior
  std::vector<double> weight_;    // per block: the weights of the hypotheses that touched it
  std::vector<uint32_t> blocks_;  // add_hypothesis: its slots' blocks
};

}  // namespace bgkmap
