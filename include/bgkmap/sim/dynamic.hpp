// Objects of a scene that change with time. Time is the scan index: scan k is cast into the scene
// as it is at time k, and the truth at time k is that scene's.
//   appear / disappear   present for appear <= k < disappear (a door that opens at scan k is a
//                        box with disappear: k; a car that leaves, the same)
//   path + speed         a walker: the shape is given where it stands at path[0]; from `appear`
//                        it moves along the path at `speed` metres per scan, and at an end of an
//                        open path turns back (a closed path loops)
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "bgkmap/sim/primitives.hpp"

namespace bgkmap::sim {

struct DynamicObject {
  std::string name;
  Primitive shape = Sphere({0, 0, 0}, 1);  // box, cylinder or sphere
  int appear = 0;
  std::optional<int> disappear;  // absent: never
  std::vector<Vec3d> path;       // empty: it stays where it is
  bool closed = false;
  double speed_m_per_scan = 0;

  // Throws std::invalid_argument with a one-line reason naming the object.
  void validate() const;
  bool present_at(int scan) const { return scan >= appear && (!disappear || scan < *disappear); }
  // Where path[0] has moved to at `scan` (path[0] itself, or the origin without a path).
  Vec3d offset_at(int scan) const;
  // The shape at `scan` (whether or not it is present then).
  Primitive shape_at(int scan) const;
  bool moves() const { return path.size() > 1 && speed_m_per_scan > 0; }
};

// The primitive moved by `offset`; a plane or height field cannot be moved (std::invalid_argument).
Primitive translated(const Primitive& primitive, const Vec3d& offset);

}  // namespace bgkmap::sim
