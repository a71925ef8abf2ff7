// 3-D DDA (Amanatides & Woo): the cells a ray or a segment passes through, in order. Shared by the
// counting method's beams and the map's ray casts (map/map_queries).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>

#include "bgkmap/core/grid.hpp"

namespace bgkmap {

// Walks the cells along origin + t * delta (t >= 0) from the cell holding origin, one face crossing
// a step; t is in units of |delta| (delta = b - a: t in [0, 1] along a segment; a unit direction:
// metres). At a tie (an edge or a corner crossed exactly) x steps before y before z.
class CellWalk {
 public:
  CellWalk(const Grid& grid, const Vec3d& origin, const Vec3d& delta)
      : resolution_(grid.resolution()), origin_{origin.x, origin.y, origin.z}, delta_{delta.x, delta.y, delta.z} {
    const CellIndex start = grid.cell_of(origin.x, origin.y, origin.z);
    cell_[0] = start.x, cell_[1] = start.y, cell_[2] = start.z;
    for (int i = 0; i < 3; ++i) {
      step_[i] = delta_[i] > 0 ? 1 : (delta_[i] < 0 ? -1 : 0);
      t_delta_[i] = step_[i] == 0 ? kNever : resolution_ / std::abs(delta_[i]);
    }
    set_boundaries();
  }

  CellIndex cell() const { return {cell_[0], cell_[1], cell_[2]}; }
  int32_t cell(int axis) const { return cell_[axis]; }
  // t at which the walk entered cell() (0 for the first cell), and at which it leaves it.
  double entry() const { return entry_; }
  double exit() const { return t_max_[next_axis()]; }

  // The axis whose face the walk crosses next.
  int next_axis() const {
    int axis = 0;
    if (t_max_[1] < t_max_[axis]) axis = 1;
    if (t_max_[2] < t_max_[axis]) axis = 2;
    return axis;
  }
  void step(int axis) {
    entry_ = t_max_[axis];
    cell_[axis] += step_[axis];
    t_max_[axis] += t_delta_[axis];
  }
  void step() { step(next_axis()); }

  // Moves the walk to the cell holding origin + t * delta, as if it had walked there (face
  // crossings measured from the origin): a walk that need not look at the cells before t.
  void skip_to(const Grid& grid, double t) {
    const CellIndex c = grid.cell_of(origin_[0] + t * delta_[0], origin_[1] + t * delta_[1], origin_[2] + t * delta_[2]);
    const int32_t to[3] = {c.x, c.y, c.z};
    for (int i = 0; i < 3; ++i)
      if (step_[i] != 0) cell_[i] = to[i];  // an axis the ray does not move along keeps its cell
    set_boundaries();
    entry_ = t;
  }

 private:
  static constexpr double kNever = std::numeric_limits<double>::infinity();

  void set_boundaries() {
    for (int i = 0; i < 3; ++i) {
      if (step_[i] == 0) {
        t_max_[i] = kNever;
        continue;
      }
      const double boundary = (cell_[i] + (step_[i] > 0 ? 1 : 0)) * resolution_;
      t_max_[i] = (boundary - origin_[i]) / delta_[i];
    }
  }

  double resolution_;
  double origin_[3], delta_[3];
  int32_t cell_[3];
  int step_[3];
  double t_max_[3], t_delta_[3];
  double entry_ = 0;
};

// Calls visit(CellIndex) for every cell the segment a->b passes through, from a's cell to b's
// cell inclusive, each once.
template <typename Visit>
void for_each_cell_on_segment(const Grid& grid, const Vec3d& a, const Vec3d& b, Visit&& visit) {
  CellWalk walk(grid, a, Vec3d{b.x - a.x, b.y - a.y, b.z - a.z});
  const CellIndex end = grid.cell_of(b.x, b.y, b.z);
  const int32_t last[3] = {end.x, end.y, end.z};
  visit(walk.cell());
  // Rounding can put the last boundary crossing just past t = 1: the step count, not t, ends it.
  int64_t steps_left = 0;
  for (int i = 0; i < 3; ++i) steps_left += std::abs(int64_t{last[i]} - walk.cell(i));
  while (steps_left-- > 0) {
    int axis = walk.next_axis();
    // Never step an axis past its end cell (a crossing mis-ordered by rounding).
    for (int i = 0; i < 3 && walk.cell(axis) == last[axis]; ++i)
      if (walk.cell(i) != last[i]) axis = i;
    walk.step(axis);
    visit(walk.cell());
  }
}

}  // namespace bgkmap
