// Height-field terrain. Over one grid cell the surface is bilinear, so along a straight ray the
// height is a quadratic in t and the first crossing is a root of a quadratic: exact, no marching.
// The ray visits the cells it crosses in order (2-D DDA) until one of them is hit.
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "bgkmap/sim/primitives.hpp"
#include "quadratic.hpp"

namespace bgkmap::sim {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
// relation() looks at the heights under a box only when it covers at most this many cells;
// larger boxes answer kMixed and are refined by the caller.
constexpr long kMaxCellsForRelation = 4096;
}  // namespace

HeightField::HeightField(double origin_x, double origin_y, double cell, double base_z,
                         std::vector<std::vector<double>> heights)
    : x0_(origin_x), y0_(origin_y), cell_(cell), base_z_(base_z), heights_(std::move(heights)) {
  if (!std::isfinite(x0_) || !std::isfinite(y0_) || !std::isfinite(cell_) || !std::isfinite(base_z_))
    throw std::invalid_argument("heightfield has a non-finite value");
  if (cell_ <= 0) throw std::invalid_argument("heightfield cell size must be positive");
  if (heights_.size() < 2 || heights_[0].size() < 2)
    throw std::invalid_argument("heightfield needs at least 2 x 2 heights");
  double lo = kInf, hi = -kInf;
  for (const auto& row : heights_) {
    if (row.size() != heights_[0].size()) throw std::invalid_argument("heightfield rows must all have the same length");
    for (double h : row) {
      if (!std::isfinite(h)) throw std::invalid_argument("heightfield has a non-finite height");
      lo = std::min(lo, h);
      hi = std::max(hi, h);
    }
  }
  if (base_z_ > lo)
    throw std::invalid_argument("heightfield base_z (" + std::to_string(base_z_) + ") is above its lowest height (" +
                                std::to_string(lo) + ")");
  bounds_ = {{x0_, y0_, base_z_}, {x0_ + (nx() - 1) * cell_, y0_ + (ny() - 1) * cell_, hi}};
}

double HeightField::height_at(double x, double y) const {
  const double fx = (x - x0_) / cell_, fy = (y - y0_) / cell_;
  const int i = std::clamp(static_cast<int>(std::floor(fx)), 0, nx() - 2);
  const int j = std::clamp(static_cast<int>(std::floor(fy)), 0, ny() - 2);
  const double u = fx - i, v = fy - j;
  const double h00 = heights_[j][i], h10 = heights_[j][i + 1], h01 = heights_[j + 1][i], h11 = heights_[j + 1][i + 1];
  return h00 * (1 - u) * (1 - v) + h10 * u * (1 - v) + h01 * (1 - u) * v + h11 * u * v;
}

bool HeightField::contains(const Vec3d& p) const {
  if (p.x < bounds_.min.x || p.x > bounds_.max.x || p.y < bounds_.min.y || p.y > bounds_.max.y) return false;
  return p.z >= base_z_ && p.z <= height_at(p.x, p.y);
}

std::optional<double> HeightField::first_hit_in_cell(const Ray& ray, int i, int j, double t_begin, double t_end) const {
  // Parametrize from the entry point (s = t - t_begin) so u, v stay within about [0, 1].
  const Vec3d p = ray.at(t_begin);
  const double u0 = (p.x - (x0_ + i * cell_)) / cell_, v0 = (p.y - (y0_ + j * cell_)) / cell_;
  const double du = ray.dir.x / cell_, dv = ray.dir.y / cell_;
  const double h00 = heights_[j][i], h10 = heights_[j][i + 1], h01 = heights_[j + 1][i], h11 = heights_[j + 1][i + 1];
  // h(u, v) = A + B u + C v + D u v
  const double A = h00, B = h10 - h00, C = h01 - h00, D = h00 - h10 - h01 + h11;
  // g(s) = z(s) - h(u(s), v(s)) = a s^2 + b s + c; inside where g <= 0.
  const double a = -D * du * dv;
  const double b = ray.dir.z - (B * du + C * dv + D * (u0 * dv + v0 * du));
  const double c = p.z - (A + B * u0 + C * v0 + D * u0 * v0);
  const auto s = first_nonpositive(a, b, c, 0.0, t_end - t_begin);
  if (!s) return std::nullopt;
  return t_begin + *s;
}

std::optional<double> HeightField::first_hit(const Ray& ray, double t_max) const {
  double ta, tb;
  if (!clip_ray_to_box(ray, bounds_, ta, tb)) return std::nullopt;
  double t = std::max(ta, 0.0);
  const double t_end = std::min(tb, t_max);
  if (t > t_end) return std::nullopt;
  // Inside the bounding box z >= base_z holds, so the solid is exactly where z <= h.
  const Vec3d start = ray.at(t);
  int i = std::clamp(static_cast<int>(std::floor((start.x - x0_) / cell_)), 0, nx() - 2);
  int j = std::clamp(static_cast<int>(std::floor((start.y - y0_) / cell_)), 0, ny() - 2);
  const int step_i = ray.dir.x > 0 ? 1 : -1, step_j = ray.dir.y > 0 ? 1 : -1;
  for (;;) {
    // Parameters at which the ray leaves cell (i, j) through its x and y sides.
    const double tx = ray.dir.x == 0 ? kInf : (x0_ + (i + (step_i > 0)) * cell_ - ray.origin.x) / ray.dir.x;
    const double ty = ray.dir.y == 0 ? kInf : (y0_ + (j + (step_j > 0)) * cell_ - ray.origin.y) / ray.dir.y;
    const double t_leave = std::min({tx, ty, t_end});
    if (const auto hit = first_hit_in_cell(ray, i, j, t, std::max(t, t_leave))) return hit;
    if (t_leave >= t_end) return std::nullopt;
    if (tx <= ty) i += step_i;
    else j += step_j;
    if (i < 0 || i > nx() - 2 || j < 0 || j > ny() - 2) return std::nullopt;
    t = std::max(t, t_leave);
  }
}

BoxRelation HeightField::relation(const Box3d& box) const {
  if (!bounds_.overlaps(box)) return BoxRelation::kOutside;
  auto cell_x = [&](double x) { return std::clamp(static_cast<int>(std::floor((x - x0_) / cell_)), 0, nx() - 2); };
  auto cell_y = [&](double y) { return std::clamp(static_cast<int>(std::floor((y - y0_) / cell_)), 0, ny() - 2); };
  const int i0 = cell_x(box.min.x), i1 = cell_x(box.max.x), j0 = cell_y(box.min.y), j1 = cell_y(box.max.y);
  if (static_cast<long>(i1 - i0 + 1) * (j1 - j0 + 1) > kMaxCellsForRelation) return BoxRelation::kMixed;
  // A bilinear patch lies between the lowest and highest of its corners.
  double lo = kInf, hi = -kInf;
  for (int j = j0; j <= j1 + 1; ++j)
    for (int i = i0; i <= i1 + 1; ++i) {
      lo = std::min(lo, heights_[j][i]);
      hi = std::max(hi, heights_[j][i]);
    }
  if (box.min.z > hi) return BoxRelation::kOutside;
  const bool within_extent = box.min.x >= bounds_.min.x && box.max.x <= bounds_.max.x && box.min.y >= bounds_.min.y &&
                             box.max.y <= bounds_.max.y;
  if (within_extent && box.min.z >= base_z_ && box.max.z <= lo) return BoxRelation::kInside;
  return BoxRelation::kMixed;
}

}  // namespace bgkmap::sim
