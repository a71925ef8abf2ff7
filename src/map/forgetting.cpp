#include "bgkmap/map/forgetting.hpp"

#include <cmath>

namespace bgkmap {

double decay_factor(double half_life_scans, uint64_t elapsed) {
  return std::exp2(-static_cast<double>(elapsed) / half_life_scans);
}

void decay_cells(Cell* cells, size_t count, const Cell& prior, double factor) {
  const double a0 = prior.alpha, b0 = prior.beta;
  for (size_t i = 0; i < count; ++i) {
    cells[i].alpha = static_cast<float>(a0 + factor * (static_cast<double>(cells[i].alpha) - a0));
    cells[i].beta = static_cast<float>(b0 + factor * (static_cast<double>(cells[i].beta) - b0));
  }
}

}  // namespace bgkmap
