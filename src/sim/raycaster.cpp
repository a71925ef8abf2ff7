#include "bgkmap/sim/raycaster.hpp"

#include <algorithm>
#include <cmath>

namespace bgkmap::sim {

namespace {
constexpr uint32_t kMaxLeafSize = 4;

// Keeps the hit with the smaller t; equal t goes to the lower index, as in the brute force.
void keep_nearest(std::optional<RayHit>& best, double t, uint32_t primitive) {
  if (!best || t < best->t || (t == best->t && primitive < best->primitive)) best = RayHit{t, primitive};
}
}  // namespace

Raycaster::Raycaster(const Scene& scene) : primitives_(scene.primitives) {
  std::vector<Box3d> boxes(primitives_.size());
  for (uint32_t i = 0; i < primitives_.size(); ++i) {
    if (const auto b = bounds(primitives_[i])) {
      boxes[i] = b->padded();  // rounding in the slab test never culls a grazing hit
      order_.push_back(i);
    } else {
      unbounded_.push_back(i);
    }
  }
  if (!order_.empty()) {
    nodes_.reserve(2 * order_.size());
    build(0, static_cast<uint32_t>(order_.size()), boxes);
  }
}

uint32_t Raycaster::build(uint32_t begin, uint32_t end, const std::vector<Box3d>& boxes) {
  const uint32_t index = static_cast<uint32_t>(nodes_.size());
  nodes_.emplace_back();
  Box3d box = Box3d::empty(), centres = Box3d::empty();
  for (uint32_t i = begin; i < end; ++i) {
    box.expand(boxes[order_[i]]);
    centres.expand(boxes[order_[i]].center());
  }
  nodes_[index].box = box;
  if (end - begin <= kMaxLeafSize) {
    nodes_[index].first = begin;
    nodes_[index].count = end - begin;
    return index;
  }
  // Median split along the axis where the centres spread most.
  const Vec3d extent = centres.max - centres.min;
  const int axis = extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
  const uint32_t mid = begin + (end - begin) / 2;
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end, [&](uint32_t a, uint32_t b) {
    return component(boxes[a].center(), axis) < component(boxes[b].center(), axis);
  });
  build(begin, mid, boxes);
  const uint32_t right = build(mid, end, boxes);
  nodes_[index].right = right;
  return index;
}

std::optional<RayHit> Raycaster::cast(const Ray& ray, double t_max) const {
  std::optional<RayHit> best;
  for (uint32_t i : unbounded_)
    if (const auto t = first_hit(primitives_[i], ray, t_max)) keep_nearest(best, *t, i);
  if (nodes_.empty()) return best;

  // Slab test with the reciprocal direction computed once per ray. A zero component gives an
  // infinite reciprocal and, for an origin exactly on a slab plane, NaN: std::min/max with the
  // running bound first return that bound, so a NaN is skipped (the box then counts as missed;
  // node boxes are padded, so no primitive can be touched there).
  const double inv[3] = {1.0 / ray.dir.x, 1.0 / ray.dir.y, 1.0 / ray.dir.z};
  const double org[3] = {ray.origin.x, ray.origin.y, ray.origin.z};
  auto entry = [&](const Node& node, double& t_in) {
    const double lo[3] = {node.box.min.x, node.box.min.y, node.box.min.z};
    const double hi[3] = {node.box.max.x, node.box.max.y, node.box.max.z};
    double t0 = 0, t1 = best ? best->t : t_max;
    for (int a = 0; a < 3; ++a) {
      const double ta = (lo[a] - org[a]) * inv[a], tb = (hi[a] - org[a]) * inv[a];
      t0 = std::max(t0, std::min(ta, tb));
      t1 = std::min(t1, std::max(ta, tb));
    }
    t_in = t0;
    return t0 <= t1;
  };
  uint32_t stack[64];
  int top = 0;
  double t_in;
  if (entry(nodes_[0], t_in)) stack[top++] = 0;
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    if (node.count > 0) {
      for (uint32_t k = node.first; k < node.first + node.count; ++k) {
        const uint32_t i = order_[k];
        if (const auto t = first_hit(primitives_[i], ray, best ? best->t : t_max)) keep_nearest(best, *t, i);
      }
      continue;
    }
    const uint32_t left = static_cast<uint32_t>(&node - nodes_.data()) + 1, right = node.right;
    double t_left, t_right;
    const bool hit_left = entry(nodes_[left], t_left), hit_right = entry(nodes_[right], t_right);
    // Nearer child on top of the stack: its hits shrink the limit for the farther one.
    if (hit_left && hit_right) {
      const bool left_first = t_left <= t_right;
      stack[top++] = left_first ? right : left;
      stack[top++] = left_first ? left : right;
    } else if (hit_left) {
      stack[top++] = left;
    } else if (hit_right) {
      stack[top++] = right;
    }
  }
  return best;
}

std::optional<RayHit> cast_brute_force(const Scene& scene, const Ray& ray, double t_max) {
  std::optional<RayHit> best;
  for (uint32_t i = 0; i < scene.primitives.size(); ++i)
    if (const auto t = first_hit(scene.primitives[i], ray, t_max)) keep_nearest(best, *t, i);
  return best;
}

}  // namespace bgkmap::sim
