// Forgetting's default on every back end: the blocks decayed on the host (integrator.hpp).
#include <algorithm>
#include <cstdint>

#include "bgkmap/integrate/integrator.hpp"
#include "bgkmap/map/forgetting.hpp"

namespace bgkmap {

void Integrator::decay_blocks(BgkMap& map, const std::vector<uint32_t>& slots, const std::vector<float>& factors,
                              IntegrateStats& stats) {
  if (slots.empty()) return;
  const HostCells cells = host_cells(map, slots, stats, HostAccess::kReadWrite);
  const Cell prior{map.params().prior.alpha0, map.params().prior.beta0};
  const size_t n = static_cast<size_t>(map.cells_per_block());
  const int64_t count = static_cast<int64_t>(slots.size());
  // Blocks are independent: the same bits on any number of threads.
#pragma omp parallel for schedule(static) num_threads(std::max(idle_host_threads(), 1))
  for (int64_t i = 0; i < count; ++i)
    decay_cells(map.block_cells(slots[static_cast<size_t>(i)]), n, prior, factors[static_cast<size_t>(i)]);
}

}  // namespace bgkmap
