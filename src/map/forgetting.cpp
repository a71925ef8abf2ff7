#include "bgkmap/map/forgetting.hpp"

#include <cmath>

#include "core/bgk_math.h"

namespace bgkmap {

double decay_factor(double half_life_scans, uint64_t elapsed) {
  return std::exp2(-static_cast<double>(elapsed) / half_life_scans);
}

void decay_cells(Cell* cells, size_t count, const Cell& prior, float factor) {
  for (size_t i = 0; i < count; ++i) {
    cells[i].alpha = bgk_decayed(cells[i].alpha, prior.alpha, factor);
    cells[i].beta = bgk_decayed(cells[i].beta, prior.beta, factor);
  }
}

}  // namespace bgkmap
