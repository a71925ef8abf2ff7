// Analytic solids of simulated scenes. Every solid is closed (its boundary is inside) and offers:
//   contains(p)          exact inside test
//   first_hit(ray, tmax) smallest t in [0, tmax] with ray.at(t) inside, or nothing; a ray that
//                        starts inside hits at t = 0
//   bounds()             axis-aligned bounding box (nothing for the unbounded half-space)
//   relation(box)        conservative: kInside / kOutside only when true of every point of the
//                        box, kMixed otherwise (used to rasterize the truth without visiting
//                        every cell)
// Constructors throw std::invalid_argument with a one-line reason for degenerate shapes.
#pragma once

#include <optional>
#include <variant>
#include <vector>

#include "bgkmap/sim/vec_math.hpp"

namespace bgkmap::sim {

enum class BoxRelation { kOutside, kInside, kMixed };

// Box of size `size` centred at `center`, rotated by roll/pitch/yaw (degrees) about its centre.
class Box {
 public:
  Box(const Vec3d& center, const Vec3d& size, const Vec3d& rpy_deg = {});
  const Vec3d& center() const { return center_; }
  Vec3d size() const { return 2.0 * half_; }
  const Vec3d& rpy_deg() const { return rpy_deg_; }

  bool contains(const Vec3d& p) const;
  std::optional<double> first_hit(const Ray& ray, double t_max) const;
  std::optional<Box3d> bounds() const;
  BoxRelation relation(const Box3d& box) const;
  // Ray parameter interval inside the solid (t over all reals); false when the line misses it.
  bool clip(const Ray& ray, double& t0, double& t1) const;

 private:
  Vec3d center_, half_, rpy_deg_;
  Mat3 rotation_;  // local -> world
};

// Capped cylinder: disc of `radius` swept from `base` to `top` (any axis direction).
class Cylinder {
 public:
  Cylinder(const Vec3d& base, const Vec3d& top, double radius);
  const Vec3d& base() const { return base_; }
  const Vec3d& top() const { return top_; }
  double radius() const { return radius_; }

  bool contains(const Vec3d& p) const;
  std::optional<double> first_hit(const Ray& ray, double t_max) const;
  std::optional<Box3d> bounds() const;
  BoxRelation relation(const Box3d& box) const;
  bool clip(const Ray& ray, double& t0, double& t1) const;

 private:
  Vec3d base_, top_, axis_;  // axis_: unit vector base -> top
  double radius_, length_;
};

class Sphere {
 public:
  Sphere(const Vec3d& center, double radius);
  const Vec3d& center() const { return center_; }
  double radius() const { return radius_; }

  bool contains(const Vec3d& p) const;
  std::optional<double> first_hit(const Ray& ray, double t_max) const;
  std::optional<Box3d> bounds() const;
  BoxRelation relation(const Box3d& box) const;
  bool clip(const Ray& ray, double& t0, double& t1) const;

 private:
  Vec3d center_;
  double radius_;
};

// Everything on the far side of a plane: {p : (p - point) . normal <= 0}. The normal points out
// of the solid, so a ground at height h is HalfSpace({0, 0, h}, {0, 0, 1}).
class HalfSpace {
 public:
  HalfSpace(const Vec3d& point, const Vec3d& normal);
  const Vec3d& point() const { return point_; }
  const Vec3d& normal() const { return normal_; }  // unit length

  bool contains(const Vec3d& p) const;
  std::optional<double> first_hit(const Ray& ray, double t_max) const;
  std::optional<Box3d> bounds() const { return std::nullopt; }
  BoxRelation relation(const Box3d& box) const;
  bool clip(const Ray& ray, double& t0, double& t1) const;

 private:
  double signed_distance(const Vec3d& p) const { return dot(p - point_, normal_); }
  Vec3d point_, normal_;
};

// Terrain: the solid between z = base_z and the bilinear surface through a grid of heights.
// heights[j][i] is the height at (origin_x + i * cell, origin_y + j * cell); at least 2 x 2
// samples, base_z not above any height. Outside the grid's x/y extent there is no solid.
class HeightField {
 public:
  HeightField(double origin_x, double origin_y, double cell, double base_z, std::vector<std::vector<double>> heights);
  double origin_x() const { return x0_; }
  double origin_y() const { return y0_; }
  double cell() const { return cell_; }
  double base_z() const { return base_z_; }
  const std::vector<std::vector<double>>& heights() const { return heights_; }

  // Height of the surface at (x, y) inside the extent (bilinear).
  double height_at(double x, double y) const;

  bool contains(const Vec3d& p) const;
  std::optional<double> first_hit(const Ray& ray, double t_max) const;
  std::optional<Box3d> bounds() const { return bounds_; }
  BoxRelation relation(const Box3d& box) const;

 private:
  int nx() const { return static_cast<int>(heights_[0].size()); }
  int ny() const { return static_cast<int>(heights_.size()); }
  // First t in [t_begin, t_end] where the ray is at or below the surface of cell (i, j).
  std::optional<double> first_hit_in_cell(const Ray& ray, int i, int j, double t_begin, double t_end) const;

  double x0_, y0_, cell_, base_z_;
  std::vector<std::vector<double>> heights_;
  Box3d bounds_;
};

using Primitive = std::variant<Box, Cylinder, Sphere, HalfSpace, HeightField>;

bool contains(const Primitive& primitive, const Vec3d& p);
std::optional<double> first_hit(const Primitive& primitive, const Ray& ray, double t_max);
std::optional<Box3d> bounds(const Primitive& primitive);
BoxRelation relation(const Primitive& primitive, const Box3d& box);
// "box", "cylinder", "sphere", "plane", "heightfield": the scene file's type names.
const char* type_name(const Primitive& primitive);

}  // namespace bgkmap::sim
