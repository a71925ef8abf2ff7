#include "bgkmap/sim/dynamic.hpp"

#include <cmath>
#include <stdexcept>
#include <type_traits>

namespace bgkmap::sim {

Primitive translated(const Primitive& primitive, const Vec3d& d) {
  return std::visit(
      [&](const auto& s) -> Primitive {
        using T = std::decay_t<decltype(s)>;
        if constexpr (std::is_same_v<T, Box>) return Box(s.center() + d, s.size(), s.rpy_deg());
        else if constexpr (std::is_same_v<T, Cylinder>) return Cylinder(s.base() + d, s.top() + d, s.radius());
        else if constexpr (std::is_same_v<T, Sphere>) return Sphere(s.center() + d, s.radius());
        else throw std::invalid_argument(std::string("a ") + type_name(primitive) + " cannot move (box, cylinder or sphere)");
      },
      primitive);
}

void DynamicObject::validate() const {
  const std::string who = "dynamic object '" + name + "': ";
  if (std::holds_alternative<HalfSpace>(shape) || std::holds_alternative<HeightField>(shape))
    throw std::invalid_argument(who + "shape must be a box, cylinder or sphere");
  if (appear < 0) throw std::invalid_argument(who + "appear must be >= 0");
  if (disappear && *disappear <= appear) throw std::invalid_argument(who + "disappear must be after appear");
  if (!(speed_m_per_scan >= 0) || !std::isfinite(speed_m_per_scan))
    throw std::invalid_argument(who + "speed must be a finite number >= 0 (metres per scan)");
  if (speed_m_per_scan > 0 && path.size() < 2) throw std::invalid_argument(who + "speed needs a path of 2 or more points");
  double length = 0;
  for (size_t i = 0; i + 1 < path.size(); ++i) length += norm(path[i + 1] - path[i]);
  if (speed_m_per_scan > 0 && !(length > 0)) throw std::invalid_argument(who + "the path has zero length");
}

Vec3d DynamicObject::offset_at(int scan) const {
  if (!moves() || scan <= appear) return {0, 0, 0};
  std::vector<Vec3d> points = path;
  if (closed) {
    points.push_back(path.front());
  } else {  // there and back: one loop of the doubled path
    for (size_t i = path.size() - 1; i-- > 0;) points.push_back(path[i]);
  }
  double loop = 0;
  for (size_t i = 0; i + 1 < points.size(); ++i) loop += norm(points[i + 1] - points[i]);
  double d = std::fmod(speed_m_per_scan * (scan - appear), loop);
  for (size_t i = 0; i + 1 < points.size(); ++i) {
    const double segment = norm(points[i + 1] - points[i]);
    if (d <= segment && segment > 0) return points[i] + (d / segment) * (points[i + 1] - points[i]) - path.front();
    d -= segment;
  }
  return {0, 0, 0};  // d == loop up to rounding: back at the start
}

Primitive DynamicObject::shape_at(int scan) const { return moves() ? translated(shape, offset_at(scan)) : shape; }

}  // namespace bgkmap::sim
