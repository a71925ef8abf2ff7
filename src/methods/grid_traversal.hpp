// 3-D DDA (Amanatides & Woo): the cells a segment passes through, in order. Internal header of
// the counting method.
#pragma once

#include <cmath>
#include <cstdlib>
#include <limits>

#include "bgkmap/core/grid.hpp"

namespace bgkmap {

// Calls visit(CellIndex) for every cell the segment a->b passes through, from a's cell to b's
// cell inclusive, each once.
template <typename Visit>
void for_each_cell_on_segment(const Grid& grid, const Vec3d& a, const Vec3d& b, Visit&& visit) {
  const double r = grid.resolution();
  const CellIndex start = grid.cell_of(a.x, a.y, a.z), end = grid.cell_of(b.x, b.y, b.z);
  const double origin[3] = {a.x, a.y, a.z};
  const double delta[3] = {b.x - a.x, b.y - a.y, b.z - a.z};
  int32_t cell[3] = {start.x, start.y, start.z};
  const int32_t last[3] = {end.x, end.y, end.z};
  int step[3];
  double t_max[3], t_delta[3];  // in units of the segment's length: t in [0, 1]
  constexpr double kNever = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 3; ++i) {
    step[i] = delta[i] > 0 ? 1 : (delta[i] < 0 ? -1 : 0);
    if (step[i] == 0) {
      t_max[i] = t_delta[i] = kNever;
      continue;
    }
    const double boundary = (cell[i] + (step[i] > 0 ? 1 : 0)) * r;
    t_max[i] = (boundary - origin[i]) / delta[i];
    t_delta[i] = r / std::abs(delta[i]);
  }
  visit(CellIndex{cell[0], cell[1], cell[2]});
  // Rounding can put the last boundary crossing just past t = 1: the step count, not t, ends it.
  int64_t steps_left = 0;
  for (int i = 0; i < 3; ++i) steps_left += std::abs(int64_t{last[i]} - cell[i]);
  while (steps_left-- > 0) {
    int axis = 0;
    if (t_max[1] < t_max[axis]) axis = 1;
    if (t_max[2] < t_max[axis]) axis = 2;
    // Never step an axis past its end cell (a crossing mis-ordered by rounding).
    for (int i = 0; i < 3 && cell[axis] == last[axis]; ++i)
      if (cell[i] != last[i]) axis = i;
    cell[axis] += step[axis];
    t_max[axis] += t_delta[axis];
    visit(CellIndex{cell[0], cell[1], cell[2]});
  }
}

}  // namespace bgkmap
