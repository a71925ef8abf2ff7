// Ray casts through a BgkMap: an exact DDA over its cells, stopped by the map's classification.
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "bgkmap/map/map_queries.hpp"
#include "core/grid_traversal.hpp"
#include "core/number_text.hpp"

namespace bgkmap {

const char* to_string(UnknownPolicy policy) { return policy == UnknownPolicy::kPass ? "pass" : "stop"; }

UnknownPolicy unknown_policy_from_string(const std::string& name) {
  if (name == "stop") return UnknownPolicy::kStop;
  if (name == "pass") return UnknownPolicy::kPass;
  throw std::invalid_argument("unknown-cell policy '" + name + "' (accepted: stop, pass)");
}

const char* to_string(RayStop stop) {
  switch (stop) {
    case RayStop::kOccupied: return "occupied";
    case RayStop::kUnknown: return "unknown";
    case RayStop::kMaxRange: return "max_range";
    case RayStop::kMapEnd: return "map_end";
  }
  return "?";
}

namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

// Posteriors of cells looked up one after another along a ray: the block's slot is kept while
// the ray stays in it.
class CellLookup {
 public:
  explicit CellLookup(const BgkMap& map) : map_(map) {}
  CellPosterior operator()(const CellIndex& cell) {
    const BlockKey key = map_.grid().block_of(cell);
    if (!valid_ || key != key_) {
      key_ = key;
      slot_ = map_.find_slot(key);
      valid_ = true;
    }
    const Cell prior{map_.params().prior.alpha0, map_.params().prior.beta0};
    if (slot_ < 0) return map_.posterior(prior);
    return map_.posterior(map_.block_cells(static_cast<uint32_t>(slot_))[map_.grid().local_index(cell)]);
  }

 private:
  const BgkMap& map_;
  bool valid_ = false;
  BlockKey key_;
  int64_t slot_ = -1;
};

// The part [t_in, t_out] of the ray origin + t * u (t >= 0) inside the box; false when it misses.
bool clip_to_box(const Vec3d& origin, const Vec3d& u, const Vec3d& lo, const Vec3d& hi, double& t_in,
                 double& t_out) {
  const double o[3] = {origin.x, origin.y, origin.z}, d[3] = {u.x, u.y, u.z};
  const double l[3] = {lo.x, lo.y, lo.z}, h[3] = {hi.x, hi.y, hi.z};
  t_in = 0;
  t_out = kInfinity;
  for (int i = 0; i < 3; ++i) {
    if (d[i] == 0) {
      if (o[i] < l[i] || o[i] > h[i]) return false;
      continue;
    }
    double a = (l[i] - o[i]) / d[i], b = (h[i] - o[i]) / d[i];
    if (a > b) std::swap(a, b);
    t_in = std::max(t_in, a);
    t_out = std::min(t_out, b);
  }
  return t_in <= t_out;
}

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument(what);
}

}  // namespace

RayCaster::RayCaster(const BgkMap& map) : map_(map) {
  if (map.block_count() == 0) return;
  BlockKey lo = map.key_of_slot(0), hi = lo;
  for (uint32_t slot = 1; slot < map.block_count(); ++slot) {
    const BlockKey& k = map.key_of_slot(slot);
    lo = {std::min(lo.x, k.x), std::min(lo.y, k.y), std::min(lo.z, k.z)};
    hi = {std::max(hi.x, k.x), std::max(hi.y, k.y), std::max(hi.z, k.z)};
  }
  const double size = map.grid().block_size();
  extent_min_ = {lo.x * size, lo.y * size, lo.z * size};
  extent_max_ = {(hi.x + 1.0) * size, (hi.y + 1.0) * size, (hi.z + 1.0) * size};
  empty_ = false;
}

namespace {

// A ray as the walk takes it: a planar map's moved onto its plane, the direction of unit length,
// no limit as +inf. Throws std::invalid_argument for a ray that has no meaning (map_queries.hpp).
struct WalkedRay {
  Vec3d origin, u;
  double limit = kInfinity;
};

WalkedRay walked_ray(const BuildParams& params, const Vec3d& origin_in, const Vec3d& direction, double max_range) {
  const bool planar = params.preprocess.planar;
  WalkedRay ray;
  ray.origin = {origin_in.x, origin_in.y, planar ? params.preprocess.plane_z_m : origin_in.z};
  const Vec3d& o = ray.origin;
  require(std::isfinite(o.x) && std::isfinite(o.y) && std::isfinite(o.z), "the ray's origin is not finite");
  require(within_key_range(o.x, o.y, o.z), "the ray's origin lies beyond the map's key range (|x|, |y|, |z| at most 1e6 m)");
  require(std::isfinite(direction.x) && std::isfinite(direction.y) && std::isfinite(direction.z),
          "the ray's direction is not finite");
  const double dz = planar ? 0.0 : direction.z;
  // hypot scales: the squares of 1e308 overflowed to an infinite length, a zero direction, a walk without end.
  const double length = std::hypot(direction.x, direction.y, dz);
  require(length > 0, planar ? "the ray's direction has no component in the plane of this planar map"
                             : "the ray's direction is zero");
  require(max_range >= 0, "max range " + number_text(max_range) + " is not a length (0: no limit)");
  ray.u = {direction.x / length, direction.y / length, dz / length};
  ray.limit = max_range == 0 ? kInfinity : max_range;
  if (ray.limit < kInfinity)
    require(within_key_range(o.x + ray.limit * ray.u.x, o.y + ray.limit * ray.u.y, o.z + ray.limit * ray.u.z),
            "max range " + number_text(max_range) + " m reaches beyond the map's key range (0: no limit)");
  return ray;
}

}  // namespace

RayCast RayCaster::cast(const Vec3d& origin_in, const Vec3d& direction, double max_range, UnknownPolicy policy) const {
  const WalkedRay ray = walked_ray(map_.params(), origin_in, direction, max_range);
  const Vec3d& origin = ray.origin;
  const Vec3d& u = ray.u;
  const double limit = ray.limit;
  const Grid& grid = map_.grid();
  const ClassifyParams& classify = map_.params().classify;
  CellLookup lookup(map_);
  CellWalk walk(grid, origin, u);
  const auto ended = [&](RayStop stop, const CellIndex& cell, double distance, const CellPosterior& p) {
    return RayCast{stop, cell, grid.cell_center_d(cell), distance, p, p.state(classify)};
  };
  const auto range_end = [&](double t_walked) {
    if (limit == kInfinity) {
      const CellIndex cell = walk.cell();
      return ended(RayStop::kMapEnd, cell, t_walked, lookup(cell));
    }
    const CellIndex cell = t_walked >= limit ? walk.cell()
                                             : map_.cell_of(origin.x + limit * u.x, origin.y + limit * u.y,
                                                            origin.z + limit * u.z);
    return ended(RayStop::kMaxRange, cell, limit, lookup(cell));
  };

  // Passing unknown cells, only the map's blocks can stop the ray: the walk skips to them and ends
  // where the ray leaves them.
  double stop_at = limit;
  if (policy == UnknownPolicy::kPass) {
    double t_in = 0, t_out = 0;
    if (empty_ || !clip_to_box(origin, u, extent_min_, extent_max_, t_in, t_out) || t_in > limit) return range_end(0);
    // Two cells short of the blocks: rounding cannot skip a cell inside them.
    if (t_in > 2 * grid.resolution()) walk.skip_to(grid, t_in - 2 * grid.resolution());
    stop_at = std::min(limit, t_out);
  }
  for (;;) {
    const CellPosterior p = lookup(walk.cell());
    const CellState state = p.state(classify);
    if (state == CellState::kOccupied) return ended(RayStop::kOccupied, walk.cell(), walk.entry(), p);
    if (state == CellState::kUnknown && policy == UnknownPolicy::kStop)
      return ended(RayStop::kUnknown, walk.cell(), walk.entry(), p);
    if (walk.exit() > stop_at) break;  // the ray ends in this cell
    walk.step();
  }
  return range_end(stop_at);
}

RayCast cast_ray(const BgkMap& map, const Vec3d& origin, const Vec3d& direction, double max_range,
                 UnknownPolicy policy) {
  return RayCaster(map).cast(origin, direction, max_range, policy);
}

}  // namespace bgkmap
