// A simulated world: a union of analytic solids, objects that come, go or move (dynamic.hpp), and
// the region its truth map covers.
#pragma once

#include <optional>
#include <vector>

#include "bgkmap/sim/dynamic.hpp"
#include "bgkmap/sim/primitives.hpp"

namespace bgkmap::sim {

struct Scene {
  std::vector<Primitive> primitives;
  // Region rasterized into the truth map. Optional for scenes of bounded solids only (then the
  // solids' bounding box); required with a plane, which has no bounding box of its own.
  std::optional<Box3d> bounds;
  // Empty for a static scene; with any, `bounds` is required.
  std::vector<DynamicObject> dynamic;

  // True when p lies in any solid (closed solids: boundary points count as inside). Static
  // solids only: see scene_at for the dynamic objects.
  bool contains(const Vec3d& p) const;
};

// The static scene as it is at time `scan`: the solids plus the dynamic objects present then, in
// their place then (appended in order after the solids); no dynamic objects left.
Scene scene_at(const Scene& scene, int scan);

// scene.bounds if given, else the bounding box of every solid; throws std::invalid_argument when
// neither exists (no solids, or only planes and no bounds).
Box3d truth_region(const Scene& scene);

}  // namespace bgkmap::sim
