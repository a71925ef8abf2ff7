// First surface along a ray in a scene: a bounding-volume hierarchy over the bounded solids plus
// a plain loop over the unbounded ones (planes). It returns exactly what testing every solid
// would (cast_brute_force), ties going to the lower primitive index.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "bgkmap/sim/scene.hpp"

namespace bgkmap::sim {

struct RayHit {
  double t = 0;            // ray parameter of the hit (metres along a unit direction)
  uint32_t primitive = 0;  // index into scene.primitives
};

class Raycaster {
 public:
  // Keeps a reference to scene.primitives: the scene must outlive the raycaster, unchanged.
  explicit Raycaster(const Scene& scene);

  // Smallest t in [0, t_max] at which the ray is inside a solid. Thread-safe (const, no state).
  std::optional<RayHit> cast(const Ray& ray, double t_max) const;

  size_t node_count() const { return nodes_.size(); }

 private:
  struct Node {
    Box3d box;
    uint32_t first = 0;  // leaf: first index into order_
    uint32_t count = 0;  // leaf: number of primitives; 0 for an inner node
    uint32_t right = 0;  // inner node: index of the right child (the left one follows the node)
  };
  uint32_t build(uint32_t begin, uint32_t end, const std::vector<Box3d>& boxes);

  const std::vector<Primitive>& primitives_;
  std::vector<uint32_t> order_;      // bounded primitives, grouped by leaf
  std::vector<uint32_t> unbounded_;  // planes: tested for every ray
  std::vector<Node> nodes_;
};

// The reference: every primitive tested.
std::optional<RayHit> cast_brute_force(const Scene& scene, const Ray& ray, double t_max);

}  // namespace bgkmap::sim
