// The blocks one observation reaches, exactly: a hit's blocks are those whose cell-centre box
// lies within the support radius r of it, a beam's those whose box lies within r of its free
// segment. No block holding a cell centre within r of the observation is missed, and each block
// is named once.
#pragma once

#include <algorithm>
#include <cstdint>
#include <limits>

#include "bgkmap/core/grid.hpp"
#include "integrate/block_window.hpp"
#include "integrate/box_distance.hpp"

namespace bgkmap {

// A hit: every block of the box of candidate blocks passing the exact point-box distance.
class HitBlocks {
 public:
  HitBlocks(const Grid& grid, const BlockReach& reach) : grid_(grid), reach_(reach), r2_(reach.r * reach.r) {}

  template <class Emit>
  void operator()(const Vec3f& p, const Emit& emit) const {
    int32_t x0, x1, y0, y1, z0, z1;
    if (!reach_.span(p.x, p.x, x0, x1) || !reach_.span(p.y, p.y, y0, y1) || !reach_.span(p.z, p.z, z0, z1)) return;
    for (int32_t z = z0; z <= z1; ++z)
      for (int32_t y = y0; y <= y1; ++y)
        for (int32_t x = x0; x <= x1; ++x) {
          const BlockKey k{x, y, z};
          if (point_box_dist2(p, grid_.block_center_box(k)) < r2_) emit(k);
        }
  }

 private:
  const Grid& grid_;
  const BlockReach reach_;
  const double r2_;
};

// A beam's free segment o + t v, t in [0, 1], from the scan's origin o: per z-slab of blocks the
// segment is clipped to the slab's reach, then per row of blocks clipped again; the x range of
// what is left gives the candidate blocks of that row, and those within reach are one run of
// them, whose ends are searched for. A candidate is accepted at once when the segment passes
// through the block's cell-centre box grown by r along one axis only (every point there is
// within r of the box); only the rest, which pass near an edge or corner, pay for the exact
// distance (within_reach).
class BeamBlocks {
 public:
  BeamBlocks(const BlockReach& reach, const Vec3f& origin)
      : reach_(reach), r2_(reach.r * reach.r), o_{origin.x, origin.y, origin.z} {}

  template <class Emit>
  void operator()(const Vec3f& b, const Emit& emit) const {
    const Segment s(o_, b);
    int32_t z0, z1;
    if (!reach_.span(std::min(o_[2], o_[2] + s.v[2]), std::max(o_[2], o_[2] + s.v[2]), z0, z1)) return;
    for (int32_t z = z0; z <= z1; ++z) {
      const Span gz = reach_span(s, 2, z), iz = inner_span(s, 2, z);
      const double tz0 = std::max(0.0, gz.t0), tz1 = std::min(1.0, gz.t1);
      if (tz0 > tz1) continue;
      int32_t y0, y1;
      const double ya = o_[1] + tz0 * s.v[1], yb = o_[1] + tz1 * s.v[1];
      if (!reach_.span(std::min(ya, yb), std::max(ya, yb), y0, y1)) continue;
      for (int32_t y = y0; y <= y1; ++y) {
        const Span gy = reach_span(s, 1, y), iy = inner_span(s, 1, y);
        const double t0 = std::max(tz0, gy.t0), t1 = std::min(tz1, gy.t1);
        if (t0 > t1) continue;
        int32_t x0, x1;
        const double xa = o_[0] + t0 * s.v[0], xb = o_[0] + t1 * s.v[0];
        if (!reach_.span(std::min(xa, xb), std::max(xa, xb), x0, x1)) continue;
        auto reaches = [&](int32_t x) {
          const Span gx = reach_span(s, 0, x), ix = inner_span(s, 0, x);
          const Span inner[3] = {ix, iy, iz}, reach[3] = {gx, gy, gz};
          const int32_t key[3] = {x, y, z};
          return meets(ix, iy, gz) || meets(ix, gy, iz) || meets(gx, iy, iz) || within_reach(s, inner, reach, key);
        };
        // The distance from the segment to block x's box is convex in x (the distance from a
        // point moving along a line to a convex set), so the blocks within reach are one run:
        // only its ends are searched for, from both sides, so the blocks inside it are not tested.
        while (x0 <= x1 && !reaches(x0)) ++x0;
        while (x1 > x0 && !reaches(x1)) --x1;
        for (int32_t x = x0; x <= x1; ++x) emit(BlockKey{x, y, z});
      }
    }
  }

 private:
  struct Segment {  // v = b - o and its inverse (0 where v is)
    double v[3], inv_v[3];
    Segment(const double* o, const Vec3f& b)
        : v{double(b.x) - o[0], double(b.y) - o[1], double(b.z) - o[2]},
          inv_v{v[0] != 0 ? 1 / v[0] : 0.0, v[1] != 0 ? 1 / v[1] : 0.0, v[2] != 0 ? 1 / v[2] : 0.0} {}
  };
  struct Span {  // parameters t of o + t v on one axis inside a block's slab
    double t0, t1;
  };
  static constexpr double kInf = std::numeric_limits<double>::infinity();

  Span slab_span(const Segment& s, int ax, double lo, double hi) const {
    if (s.v[ax] == 0) return (o_[ax] >= lo && o_[ax] <= hi) ? Span{-kInf, kInf} : Span{kInf, -kInf};
    const double ta = (lo - o_[ax]) * s.inv_v[ax], tb = (hi - o_[ax]) * s.inv_v[ax];
    return ta < tb ? Span{ta, tb} : Span{tb, ta};
  }
  // The slab of block k on axis `ax`: its cell centres' interval (inner) and that grown by r (reach).
  Span inner_span(const Segment& s, int ax, int32_t k) const {
    return slab_span(s, ax, k * reach_.bs + reach_.h, (k + 1) * reach_.bs - reach_.h);
  }
  Span reach_span(const Segment& s, int ax, int32_t k) const {
    return slab_span(s, ax, k * reach_.bs + reach_.h - reach_.r - reach_.pad,
                     (k + 1) * reach_.bs - reach_.h + reach_.r + reach_.pad);
  }
  static bool meets(const Span& a, const Span& b, const Span& c) {  // within t in [0, 1]
    return std::max({0.0, a.t0, b.t0, c.t0}) <= std::min({1.0, a.t1, b.t1, c.t1});
  }
  bool within_reach(const Segment& s, const Span* inner, const Span* reach, const int32_t* key) const;

  const BlockReach reach_;
  const double r2_;
  const double o_[3];
};

// For the candidates the face test leaves (the segment passes the block near an edge or corner):
// the squared distance from o + t v to the block's cell-centre box, minimised over the t where
// the segment is inside the grown box (elsewhere it is farther than r). In t-space an axis that
// moves contributes v_a^2 (t - clamp(t, inner_a))^2, so the distance is a convex piecewise
// quadratic with breaks at the inner spans' ends; its slope is found to change sign between two
// neighbouring breaks, where it is linear. The same decisions as segment_box_dist2
// (tests/test_bucketing.cpp compares them) at a fraction of its cost.
inline bool BeamBlocks::within_reach(const Segment& s, const Span* inner, const Span* reach, const int32_t* key) const {
  const double t_lo = std::max({0.0, reach[0].t0, reach[1].t0, reach[2].t0});
  const double t_hi = std::min({1.0, reach[0].t1, reach[1].t1, reach[2].t1});
  if (t_lo > t_hi) return false;
  double still = 0;  // axes along which the segment does not move: a constant distance
  double w[3], i0[3], i1[3];
  int moving = 0;
  for (int ax = 0; ax < 3; ++ax) {
    if (s.v[ax] == 0) {
      const double lo = key[ax] * reach_.bs + reach_.h, hi = (key[ax] + 1) * reach_.bs - reach_.h;
      const double e = o_[ax] < lo ? lo - o_[ax] : (o_[ax] > hi ? o_[ax] - hi : 0.0);
      still += e * e;
    } else {
      w[moving] = s.v[ax] * s.v[ax];
      i0[moving] = inner[ax].t0;
      i1[moving] = inner[ax].t1;
      ++moving;
    }
  }
  auto slope = [&](double t) {  // half the derivative
    double sum = 0;
    for (int m = 0; m < moving; ++m) sum += w[m] * (t - std::clamp(t, i0[m], i1[m]));
    return sum;
  };
  double t = t_lo;
  const double s_lo = slope(t_lo);
  if (s_lo < 0) {
    const double s_hi = slope(t_hi);
    if (s_hi <= 0) {
      t = t_hi;
    } else {
      double left = t_lo, s_left = s_lo, right = t_hi, s_right = s_hi;
      for (int m = 0; m < moving; ++m)
        for (const double p : {i0[m], i1[m]}) {
          if (!(p > left && p < right)) continue;
          const double sp = slope(p);
          if (sp < 0) {
            left = p;
            s_left = sp;
          } else if (sp > 0) {
            right = p;
            s_right = sp;
          } else {
            left = right = p;
          }
        }
      t = left == right ? left : left - s_left * (right - left) / (s_right - s_left);
    }
  }
  double d2 = still;
  for (int m = 0; m < moving; ++m) {
    const double e = t - std::clamp(t, i0[m], i1[m]);
    d2 += w[m] * e * e;
  }
  return d2 < r2_;
}

}  // namespace bgkmap
