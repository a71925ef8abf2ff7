// Double-precision vector arithmetic for the simulator's exact geometry (ray casts, inside tests).
// The operators live in bgkmap::sim so they never clash with arithmetic other modules define.
#pragma once

#include <cmath>

#include "bgkmap/core/grid.hpp"

namespace bgkmap::sim {

inline Vec3d operator+(const Vec3d& a, const Vec3d& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Vec3d operator-(const Vec3d& a, const Vec3d& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Vec3d operator*(double s, const Vec3d& a) { return {s * a.x, s * a.y, s * a.z}; }
inline double dot(const Vec3d& a, const Vec3d& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3d cross(const Vec3d& a, const Vec3d& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double norm(const Vec3d& a) { return std::sqrt(dot(a, a)); }
inline Vec3d normalized(const Vec3d& a) { return (1.0 / norm(a)) * a; }
inline double component(const Vec3d& a, int axis) { return axis == 0 ? a.x : (axis == 1 ? a.y : a.z); }

// Row-major 3x3 matrix; used for rotations (columns = the rotated frame's axes in world frame).
struct Mat3 {
  double m[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};

  Vec3d operator*(const Vec3d& v) const {
    return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z, m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
            m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z};
  }
  // Transpose times v: world -> local for a rotation.
  Vec3d transposed_times(const Vec3d& v) const {
    return {m[0][0] * v.x + m[1][0] * v.y + m[2][0] * v.z, m[0][1] * v.x + m[1][1] * v.y + m[2][1] * v.z,
            m[0][2] * v.x + m[1][2] * v.y + m[2][2] * v.z};
  }
};

// R = Rz(yaw) * Ry(pitch) * Rx(roll), angles in degrees (the usual roll/pitch/yaw convention).
Mat3 rotation_from_rpy_deg(const Vec3d& rpy_deg);

// Closed axis-aligned box [min, max].
struct Box3d {
  Vec3d min, max;

  bool contains(const Vec3d& p) const {
    return p.x >= min.x && p.x <= max.x && p.y >= min.y && p.y <= max.y && p.z >= min.z && p.z <= max.z;
  }
  bool overlaps(const Box3d& o) const {
    return min.x <= o.max.x && o.min.x <= max.x && min.y <= o.max.y && o.min.y <= max.y && min.z <= o.max.z &&
           o.min.z <= max.z;
  }
  Vec3d corner(int i) const { return {(i & 1) ? max.x : min.x, (i & 2) ? max.y : min.y, (i & 4) ? max.z : min.z}; }
  Vec3d center() const { return 0.5 * (min + max); }
  void expand(const Box3d& o);
  void expand(const Vec3d& p);
  // Grown by 1e-9 of its largest coordinate (at least 1e-9 m): a bounding box computed through
  // rotations, so grown, never excludes a point that a solid's exact inside test includes.
  Box3d padded() const;
  static Box3d empty();
};

// A ray o + t d, t >= 0; d need not be unit length (t is then in units of |d|).
struct Ray {
  Vec3d origin, dir;
  Vec3d at(double t) const { return origin + t * dir; }
};

// Parameter interval [t0, t1] of a ray over the closed box; false when they do not meet.
// Components of dir may be zero.
bool clip_ray_to_box(const Ray& ray, const Box3d& box, double& t0, double& t1);

}  // namespace bgkmap::sim
