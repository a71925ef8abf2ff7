// Forgetting: a map's evidence decays toward the prior with a half-life in scans,
// alpha <- alpha0 + lambda^dt (alpha - alpha0), beta likewise, lambda = 2^(-1/H)
// (docs/ALGORITHM.md, "Forgetting"). Applied lazily per block: a block keeps the scan its cells
// were last decayed to and is decayed in one step when a scan next touches it; a read sees every
// block decayed to the map's time (BgkMap::settled).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "bgkmap/map/internal/cell_pool.hpp"

namespace bgkmap {

struct Forgetting {
  double half_life_scans = 0;  // H; 0: off, the map keeps every observation at full weight
  uint64_t now = 0;            // the map's time: scans inserted so far (an empty scan counts)
  std::vector<uint64_t> block_time;  // per slot: the scan its cells were last decayed to (kept only when on)

  bool on() const { return half_life_scans > 0; }
};

// lambda^elapsed = 2^(-elapsed / H), in double: one exp2 for any gap.
double decay_factor(double half_life_scans, uint64_t elapsed);

// Every cell of a block moved toward `prior` by `factor` (decay_factor rounded to float):
// prior + factor (value - prior) with one fused multiply-add, as the OpenCL back end's
// bgk_pool_decay computes it (core/bgk_math.h). A cell at the prior stays there bit for bit.
void decay_cells(Cell* cells, size_t count, const Cell& prior, float factor);

}  // namespace bgkmap
