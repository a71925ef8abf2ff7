// Random primitives for the simulator's tests.
#pragma once

#include <random>
#include <vector>

#include "bgkmap/sim/primitives.hpp"

namespace bgkmap::sim::testing_support {

inline Box random_box(std::mt19937& rng, double spread) {
  std::uniform_real_distribution<double> pos(-spread, spread), size(0.2, 2.5), angle(-180, 180);
  const bool rotated = rng() % 2 == 0;
  return Box({pos(rng), pos(rng), pos(rng)}, {size(rng), size(rng), size(rng)},
             rotated ? Vec3d{angle(rng), angle(rng), angle(rng)} : Vec3d{});
}

inline Cylinder random_cylinder(std::mt19937& rng, double spread) {
  std::uniform_real_distribution<double> pos(-spread, spread), off(-1.5, 1.5), radius(0.1, 1.2);
  const Vec3d base{pos(rng), pos(rng), pos(rng)};
  Vec3d top = base + Vec3d{off(rng), off(rng), off(rng)};
  if (rng() % 3 == 0) top = base + Vec3d{0, 0, 1.5};  // upright, as trees and pillars are
  return Cylinder(base, top, radius(rng));
}

inline Sphere random_sphere(std::mt19937& rng, double spread) {
  std::uniform_real_distribution<double> pos(-spread, spread), radius(0.1, 1.5);
  return Sphere({pos(rng), pos(rng), pos(rng)}, radius(rng));
}

inline HalfSpace random_half_space(std::mt19937& rng, double spread) {
  std::uniform_real_distribution<double> pos(-spread, spread), dir(-1, 1);
  Vec3d n{dir(rng), dir(rng), dir(rng)};
  if (norm(n) < 1e-3) n = {0, 0, 1};
  return HalfSpace({pos(rng), pos(rng), pos(rng)}, n);
}

inline HeightField random_height_field(std::mt19937& rng, double spread) {
  std::uniform_real_distribution<double> pos(-spread, spread), cell(0.2, 1.0), height(-1, 1);
  std::uniform_int_distribution<int> samples(2, 6);
  const int nx = samples(rng), ny = samples(rng);
  const double z0 = pos(rng);
  std::vector<std::vector<double>> h(ny, std::vector<double>(nx));
  double lowest = 1e9;
  for (auto& row : h)
    for (double& v : row) lowest = std::min(lowest, v = z0 + height(rng));
  return HeightField(pos(rng), pos(rng), cell(rng), lowest - 0.5, h);
}

// `count` of each kind: box, cylinder, sphere, half-space, height field.
inline std::vector<Primitive> random_primitives(std::mt19937& rng, int count, double spread = 2.0) {
  std::vector<Primitive> out;
  for (int i = 0; i < count; ++i) {
    out.push_back(random_box(rng, spread));
    out.push_back(random_cylinder(rng, spread));
    out.push_back(random_sphere(rng, spread));
    out.push_back(random_half_space(rng, spread));
    out.push_back(random_height_field(rng, spread));
  }
  return out;
}

}  // namespace bgkmap::sim::testing_support
