// Plain reference for tests and checks: one cell against every observation in double precision,
// world coordinates, no bucketing (only a per-axis bounding-box early-out). Slow by design; the
// back ends are tested against it.
#pragma once

#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/core/params.hpp"
#include "bgkmap/integrate/observations.hpp"

namespace bgkmap {

struct BruteForcePosterior {
  double alpha = 0, beta = 0;
};

// Posterior of the cell centred at `center` (exact, see Grid::cell_center_d) after all `scans`
// (prior included).
BruteForcePosterior brute_force_cell(const Vec3d& center, const std::vector<ScanObservations>& scans,
                                     const BuildParams& params);

}  // namespace bgkmap
