#include "bgkmap/core/scan.hpp"

namespace bgkmap {

Vec3f Pose::rotate(const Vec3f& v) const {
  // v' = q v q*, expanded: v + 2w (u x v) + 2 u x (u x v) with u = (qx, qy, qz).
  const float tx = 2 * (qy * v.z - qz * v.y);
  const float ty = 2 * (qz * v.x - qx * v.z);
  const float tz = 2 * (qx * v.y - qy * v.x);
  return {v.x + qw * tx + (qy * tz - qz * ty), v.y + qw * ty + (qz * tx - qx * tz),
          v.z + qw * tz + (qx * ty - qy * tx)};
}

Vec3f Pose::transform(const Vec3f& v) const {
  const Vec3f r = rotate(v);
  return {r.x + position.x, r.y + position.y, r.z + position.z};
}

}  // namespace bgkmap
