// The presets' axis-aligned boxes, given by their corners.
#pragma once

#include <cmath>

#include "bgkmap/sim/primitives.hpp"

namespace bgkmap::sim {

// Centre and size rounded to nanometres so that the scene file reads 0.2 rather than
// 0.20000000000000018.
inline Box box_between(const Vec3d& lo, const Vec3d& hi) {
  const auto tidy = [](double v) { return std::round(v * 1e9) / 1e9; };
  const Vec3d c = 0.5 * (lo + hi), s = hi - lo;
  return Box({tidy(c.x), tidy(c.y), tidy(c.z)}, {tidy(s.x), tidy(s.y), tidy(s.z)});
}

}  // namespace bgkmap::sim
