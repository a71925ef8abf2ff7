#include "integrate/box_distance.hpp"

#include <algorithm>

namespace bgkmap {

double point_box_dist2(const Vec3f& p, const Aabb& box) {
  const double pv[3] = {p.x, p.y, p.z};
  const double lo[3] = {box.min.x, box.min.y, box.min.z};
  const double hi[3] = {box.max.x, box.max.y, box.max.z};
  double d2 = 0;
  for (int i = 0; i < 3; ++i) {
    const double d = pv[i] < lo[i] ? lo[i] - pv[i] : (pv[i] > hi[i] ? pv[i] - hi[i] : 0.0);
    d2 += d * d;
  }
  return d2;
}

double segment_box_dist2(const Vec3f& a, const Vec3f& b, const Aabb& box) {
  // f(t) = dist^2(a + t v, box) is convex and piecewise quadratic in t, with breaks where a
  // coordinate crosses a face plane. Minimise the quadratic exactly on each piece.
  const double o[3] = {a.x, a.y, a.z};
  const double v[3] = {double(b.x) - a.x, double(b.y) - a.y, double(b.z) - a.z};
  const double lo[3] = {box.min.x, box.min.y, box.min.z};
  const double hi[3] = {box.max.x, box.max.y, box.max.z};
  double breaks[8];
  int n = 0;
  breaks[n++] = 0.0;
  breaks[n++] = 1.0;
  for (int i = 0; i < 3; ++i) {
    if (v[i] == 0) continue;
    for (const double plane : {lo[i], hi[i]}) {
      const double t = (plane - o[i]) / v[i];
      if (t > 0 && t < 1) breaks[n++] = t;
    }
  }
  for (int i = 1; i < n; ++i)  // insertion sort: at most 8 values
    for (int j = i; j > 0 && breaks[j - 1] > breaks[j]; --j) std::swap(breaks[j - 1], breaks[j]);
  auto f = [&](double t) {
    double d2 = 0;
    for (int i = 0; i < 3; ++i) {
      const double x = o[i] + t * v[i];
      const double d = x < lo[i] ? lo[i] - x : (x > hi[i] ? x - hi[i] : 0.0);
      d2 += d * d;
    }
    return d2;
  };
  double best = std::min(f(0.0), f(1.0));
  for (int k = 0; k + 1 < n; ++k) {
    const double t0 = breaks[k], t1 = breaks[k + 1];
    if (t1 <= t0) continue;
    const double tm = 0.5 * (t0 + t1);
    // On this piece each axis is either inside its slab or (x - plane)^2 for a fixed plane.
    double qa = 0, qb = 0;  // f(t) = qa t^2 + qb t + const
    for (int i = 0; i < 3; ++i) {
      const double x = o[i] + tm * v[i];
      double plane;
      if (x < lo[i]) plane = lo[i];
      else if (x > hi[i]) plane = hi[i];
      else continue;
      qa += v[i] * v[i];
      qb += 2 * v[i] * (o[i] - plane);
    }
    if (qa > 0) {
      const double t = std::clamp(-qb / (2 * qa), t0, t1);
      best = std::min(best, f(t));
    }
  }
  return best;
}

}  // namespace bgkmap
