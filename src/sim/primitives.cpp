// The convex primitives: each clips a ray to the parameter interval inside its solid, and the
// first hit is that interval's first point at or after t = 0.
#include "bgkmap/sim/primitives.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "quadratic.hpp"

namespace bgkmap::sim {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();

bool finite(const Vec3d& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

template <class Solid>
std::optional<double> first_hit_of_convex(const Solid& solid, const Ray& ray, double t_max) {
  double t0, t1;
  if (!solid.clip(ray, t0, t1) || t1 < 0) return std::nullopt;
  const double t = std::max(t0, 0.0);
  if (t > t_max) return std::nullopt;
  return t;
}

template <class Solid>
bool all_corners_inside(const Solid& solid, const Box3d& box) {
  for (int i = 0; i < 8; ++i)
    if (!solid.contains(box.corner(i))) return false;
  return true;
}

// A convex solid contains a box exactly when it contains the box's corners; it cannot touch a
// box outside its (padded) bounding box.
template <class Solid>
BoxRelation relation_of_convex(const Solid& solid, const Box3d& box) {
  if (!solid.bounds()->padded().overlaps(box)) return BoxRelation::kOutside;
  return all_corners_inside(solid, box) ? BoxRelation::kInside : BoxRelation::kMixed;
}

// Narrows [t0, t1] to the slab lo <= o + t d <= hi of one axis; false when it becomes empty.
bool clip_slab(double o, double d, double lo, double hi, double& t0, double& t1) {
  if (d == 0) return o >= lo && o <= hi;
  double ta = (lo - o) / d, tb = (hi - o) / d;
  if (ta > tb) std::swap(ta, tb);
  t0 = std::max(t0, ta);
  t1 = std::min(t1, tb);
  return t0 <= t1;
}
}  // namespace

Mat3 rotation_from_rpy_deg(const Vec3d& rpy_deg) {
  const double k = M_PI / 180.0;
  const double cr = std::cos(rpy_deg.x * k), sr = std::sin(rpy_deg.x * k);
  const double cp = std::cos(rpy_deg.y * k), sp = std::sin(rpy_deg.y * k);
  const double cy = std::cos(rpy_deg.z * k), sy = std::sin(rpy_deg.z * k);
  Mat3 r;
  r.m[0][0] = cy * cp, r.m[0][1] = cy * sp * sr - sy * cr, r.m[0][2] = cy * sp * cr + sy * sr;
  r.m[1][0] = sy * cp, r.m[1][1] = sy * sp * sr + cy * cr, r.m[1][2] = sy * sp * cr - cy * sr;
  r.m[2][0] = -sp, r.m[2][1] = cp * sr, r.m[2][2] = cp * cr;
  return r;
}

Box3d Box3d::empty() { return {{kInf, kInf, kInf}, {-kInf, -kInf, -kInf}}; }

void Box3d::expand(const Vec3d& p) {
  min = {std::min(min.x, p.x), std::min(min.y, p.y), std::min(min.z, p.z)};
  max = {std::max(max.x, p.x), std::max(max.y, p.y), std::max(max.z, p.z)};
}

void Box3d::expand(const Box3d& o) {
  expand(o.min);
  expand(o.max);
}

Box3d Box3d::padded() const {
  const double scale = std::max({std::abs(min.x), std::abs(min.y), std::abs(min.z), std::abs(max.x), std::abs(max.y),
                                 std::abs(max.z), 1.0});
  const double e = 1e-9 * scale;
  return {{min.x - e, min.y - e, min.z - e}, {max.x + e, max.y + e, max.z + e}};
}

bool clip_ray_to_box(const Ray& ray, const Box3d& box, double& t0, double& t1) {
  t0 = -kInf;
  t1 = kInf;
  return clip_slab(ray.origin.x, ray.dir.x, box.min.x, box.max.x, t0, t1) &&
         clip_slab(ray.origin.y, ray.dir.y, box.min.y, box.max.y, t0, t1) &&
         clip_slab(ray.origin.z, ray.dir.z, box.min.z, box.max.z, t0, t1);
}

// ---- Box

Box::Box(const Vec3d& center, const Vec3d& size, const Vec3d& rpy_deg)
    : center_(center), half_(0.5 * size), rpy_deg_(rpy_deg), rotation_(rotation_from_rpy_deg(rpy_deg)) {
  if (!finite(center) || !finite(size) || !finite(rpy_deg)) throw std::invalid_argument("box has a non-finite value");
  if (size.x <= 0 || size.y <= 0 || size.z <= 0) throw std::invalid_argument("box size must be positive on every axis");
}

bool Box::contains(const Vec3d& p) const {
  const Vec3d l = rotation_.transposed_times(p - center_);
  return std::abs(l.x) <= half_.x && std::abs(l.y) <= half_.y && std::abs(l.z) <= half_.z;
}

bool Box::clip(const Ray& ray, double& t0, double& t1) const {
  const Ray local{rotation_.transposed_times(ray.origin - center_), rotation_.transposed_times(ray.dir)};
  const Box3d extent{{-half_.x, -half_.y, -half_.z}, half_};
  return clip_ray_to_box(local, extent, t0, t1);
}

std::optional<double> Box::first_hit(const Ray& ray, double t_max) const { return first_hit_of_convex(*this, ray, t_max); }

std::optional<Box3d> Box::bounds() const {
  Vec3d e;
  const auto& m = rotation_.m;
  e.x = std::abs(m[0][0]) * half_.x + std::abs(m[0][1]) * half_.y + std::abs(m[0][2]) * half_.z;
  e.y = std::abs(m[1][0]) * half_.x + std::abs(m[1][1]) * half_.y + std::abs(m[1][2]) * half_.z;
  e.z = std::abs(m[2][0]) * half_.x + std::abs(m[2][1]) * half_.y + std::abs(m[2][2]) * half_.z;
  return Box3d{center_ - e, center_ + e};
}

BoxRelation Box::relation(const Box3d& box) const { return relation_of_convex(*this, box); }

// ---- Cylinder

Cylinder::Cylinder(const Vec3d& base, const Vec3d& top, double radius) : base_(base), top_(top), radius_(radius) {
  if (!finite(base) || !finite(top) || !std::isfinite(radius)) throw std::invalid_argument("cylinder has a non-finite value");
  if (radius <= 0) throw std::invalid_argument("cylinder radius must be positive");
  length_ = norm(top - base);
  if (length_ <= 0) throw std::invalid_argument("cylinder base and top must differ");
  axis_ = (1.0 / length_) * (top - base);
}

bool Cylinder::contains(const Vec3d& p) const {
  const Vec3d w = p - base_;
  const double s = dot(w, axis_);
  if (s < 0 || s > length_) return false;
  const Vec3d radial = w - s * axis_;
  return dot(radial, radial) <= radius_ * radius_;
}

bool Cylinder::clip(const Ray& ray, double& t0, double& t1) const {
  const Vec3d w = ray.origin - base_;
  const double ws = dot(w, axis_), ds = dot(ray.dir, axis_);
  t0 = -kInf;
  t1 = kInf;
  if (!clip_slab(ws, ds, 0, length_, t0, t1)) return false;
  // Distance from the axis: |wp + t dp|^2 <= r^2, wp and dp the parts across the axis.
  const Vec3d wp = w - ws * axis_, dp = ray.dir - ds * axis_;
  const double a = dot(dp, dp), b = 2 * dot(wp, dp), c = dot(wp, wp) - radius_ * radius_;
  if (a == 0) return c <= 0;  // parallel to the axis
  double r0, r1;
  if (!nonpositive_interval(a, b, c, r0, r1)) return false;
  t0 = std::max(t0, r0);
  t1 = std::min(t1, r1);
  return t0 <= t1;
}

std::optional<double> Cylinder::first_hit(const Ray& ray, double t_max) const {
  return first_hit_of_convex(*this, ray, t_max);
}

std::optional<Box3d> Cylinder::bounds() const {
  // The end discs reach r * sqrt(1 - a_i^2) from the axis along world axis i.
  const Vec3d e{radius_ * std::sqrt(std::max(0.0, 1 - axis_.x * axis_.x)),
                radius_ * std::sqrt(std::max(0.0, 1 - axis_.y * axis_.y)),
                radius_ * std::sqrt(std::max(0.0, 1 - axis_.z * axis_.z))};
  Box3d b = Box3d::empty();
  b.expand(base_ - e);
  b.expand(base_ + e);
  b.expand(top_ - e);
  b.expand(top_ + e);
  return b;
}

BoxRelation Cylinder::relation(const Box3d& box) const { return relation_of_convex(*this, box); }

// ---- Sphere

Sphere::Sphere(const Vec3d& center, double radius) : center_(center), radius_(radius) {
  if (!finite(center) || !std::isfinite(radius)) throw std::invalid_argument("sphere has a non-finite value");
  if (radius <= 0) throw std::invalid_argument("sphere radius must be positive");
}

bool Sphere::contains(const Vec3d& p) const {
  const Vec3d w = p - center_;
  return dot(w, w) <= radius_ * radius_;
}

bool Sphere::clip(const Ray& ray, double& t0, double& t1) const {
  const Vec3d w = ray.origin - center_;
  const double a = dot(ray.dir, ray.dir), b = 2 * dot(w, ray.dir), c = dot(w, w) - radius_ * radius_;
  if (a == 0) {
    t0 = -kInf;
    t1 = kInf;
    return c <= 0;
  }
  return nonpositive_interval(a, b, c, t0, t1);
}

std::optional<double> Sphere::first_hit(const Ray& ray, double t_max) const { return first_hit_of_convex(*this, ray, t_max); }

std::optional<Box3d> Sphere::bounds() const {
  const Vec3d e{radius_, radius_, radius_};
  return Box3d{center_ - e, center_ + e};
}

BoxRelation Sphere::relation(const Box3d& box) const {
  // Nearest and farthest points of the box from the centre decide it exactly.
  double near2 = 0, far2 = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const double c = component(center_, axis), lo = component(box.min, axis), hi = component(box.max, axis);
    const double below = lo - c, above = c - hi;
    const double gap = std::max({below, above, 0.0});
    near2 += gap * gap;
    const double reach = std::max(std::abs(c - lo), std::abs(c - hi));
    far2 += reach * reach;
  }
  const double r2 = radius_ * radius_;
  if (near2 > r2) return BoxRelation::kOutside;
  return far2 <= r2 ? BoxRelation::kInside : BoxRelation::kMixed;
}

// ---- HalfSpace

HalfSpace::HalfSpace(const Vec3d& point, const Vec3d& normal) : point_(point) {
  if (!finite(point) || !finite(normal)) throw std::invalid_argument("plane has a non-finite value");
  const double length = norm(normal);
  if (length == 0) throw std::invalid_argument("plane normal must not be zero");
  // A unit normal is kept bit for bit, so that writing and reading a scene file changes nothing.
  normal_ = std::abs(length - 1) <= 1e-15 ? normal : (1.0 / length) * normal;
}

bool HalfSpace::contains(const Vec3d& p) const { return signed_distance(p) <= 0; }

bool HalfSpace::clip(const Ray& ray, double& t0, double& t1) const {
  const double f0 = signed_distance(ray.origin), fd = dot(ray.dir, normal_);
  t0 = -kInf;
  t1 = kInf;
  if (fd == 0) return f0 <= 0;
  const double t = -f0 / fd;
  (fd > 0 ? t1 : t0) = t;  // moving out of the solid: inside before t; moving in: inside after t
  return true;
}

std::optional<double> HalfSpace::first_hit(const Ray& ray, double t_max) const {
  return first_hit_of_convex(*this, ray, t_max);
}

BoxRelation HalfSpace::relation(const Box3d& box) const {
  double lo = kInf, hi = -kInf;
  for (int i = 0; i < 8; ++i) {
    const double d = signed_distance(box.corner(i));
    lo = std::min(lo, d);
    hi = std::max(hi, d);
  }
  if (lo > 0) return BoxRelation::kOutside;
  return hi <= 0 ? BoxRelation::kInside : BoxRelation::kMixed;
}

// ---- Dispatch

bool contains(const Primitive& primitive, const Vec3d& p) {
  return std::visit([&](const auto& s) { return s.contains(p); }, primitive);
}

std::optional<double> first_hit(const Primitive& primitive, const Ray& ray, double t_max) {
  return std::visit([&](const auto& s) { return s.first_hit(ray, t_max); }, primitive);
}

std::optional<Box3d> bounds(const Primitive& primitive) {
  return std::visit([](const auto& s) { return s.bounds(); }, primitive);
}

BoxRelation relation(const Primitive& primitive, const Box3d& box) {
  return std::visit([&](const auto& s) { return s.relation(box); }, primitive);
}

const char* type_name(const Primitive& primitive) {
  static const char* const names[] = {"box", "cylinder", "sphere", "plane", "heightfield"};
  return names[primitive.index()];
}

}  // namespace bgkmap::sim
