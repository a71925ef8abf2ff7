// Exact distances from a point and from a segment to an axis-aligned box: the reach tests of
// bucketing and the references its tests and the distributed build's routing check against.
#pragma once

#include "bgkmap/core/grid.hpp"

namespace bgkmap {

// Squared distance from a point to a box (0 inside).
double point_box_dist2(const Vec3f& p, const Aabb& box);
// Exact squared distance between the segment a->b and a box (0 if they meet).
double segment_box_dist2(const Vec3f& a, const Vec3f& b, const Aabb& box);

}  // namespace bgkmap
