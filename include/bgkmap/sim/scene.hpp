// A simulated world: a union of analytic solids and the region its truth map covers.
#pragma once

#include <optional>
#include <vector>

#include "bgkmap/sim/primitives.hpp"

namespace bgkmap::sim {

struct Scene {
  std::vector<Primitive> primitives;
  // Region rasterized into the truth map. Optional for scenes of bounded solids only (then the
  // solids' bounding box); required with a plane, which has no bounding box of its own.
  std::optional<Box3d> bounds;

  // True when p lies in any solid (closed solids: boundary points count as inside).
  bool contains(const Vec3d& p) const;
};

// scene.bounds if given, else the bounding box of every solid; throws std::invalid_argument when
// neither exists (no solids, or only planes and no bounds).
Box3d truth_region(const Scene& scene);

}  // namespace bgkmap::sim
