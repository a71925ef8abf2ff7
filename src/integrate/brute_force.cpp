#include "integrate/brute_force.hpp"

#include <algorithm>
#include <cmath>

namespace bgkmap {

namespace {

// Written independently of bgk_math.h (double precision, different expression order) so that it
// checks the shared math rather than repeating it.
double sparse_kernel(double d, double ell, double sigma0) {
  if (d >= ell) return 0.0;
  const double pi = 3.14159265358979323846;
  return sigma0 * ((2.0 + std::cos(2.0 * pi * d / ell)) / 3.0 * (1.0 - d / ell) +
                   std::sin(2.0 * pi * d / ell) / (2.0 * pi));
}

double segment_distance(const Vec3d& p, const Vec3f& a, const Vec3f& b) {
  const double v[3] = {double(b.x) - a.x, double(b.y) - a.y, double(b.z) - a.z};
  const double w[3] = {p.x - a.x, p.y - a.y, p.z - a.z};
  const double vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
  const double t = vv > 0 ? std::clamp((w[0] * v[0] + w[1] * v[1] + w[2] * v[2]) / vv, 0.0, 1.0) : 0.0;
  const double d[3] = {w[0] - t * v[0], w[1] - t * v[1], w[2] - t * v[2]};
  return std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
}

double point_distance(const Vec3d& p, const Vec3f& q) {
  const double d[3] = {p.x - q.x, p.y - q.y, p.z - q.z};
  return std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
}

bool in_cell(const Vec3d& c, double half, const Vec3f& p) {
  return p.x >= c.x - half && p.x < c.x + half && p.y >= c.y - half && p.y < c.y + half &&
         p.z >= c.z - half && p.z < c.z + half;
}

// Does the segment a->b meet the closed box centred at c? (sampled-free slab test in double)
bool segment_meets_cell(const Vec3d& c, double half, const Vec3f& a, const Vec3f& b) {
  double t0 = 0, t1 = 1;
  const double o[3] = {a.x, a.y, a.z}, v[3] = {double(b.x) - a.x, double(b.y) - a.y, double(b.z) - a.z};
  const double cc[3] = {c.x, c.y, c.z};
  for (int i = 0; i < 3; ++i) {
    const double lo = cc[i] - half, hi = cc[i] + half;
    if (v[i] == 0) {
      if (o[i] < lo || o[i] > hi) return false;
      continue;
    }
    double ta = (lo - o[i]) / v[i], tb = (hi - o[i]) / v[i];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  return true;
}

}  // namespace

BruteForcePosterior brute_force_cell(const Vec3d& center, const std::vector<ScanObservations>& scans,
                                     const BuildParams& params, double forget_half_life) {
  BruteForcePosterior post{params.prior.alpha0, params.prior.beta0};
  const KernelParams& k = params.kernel;
  const double half = 0.5 * params.grid.resolution_m;
  // Observations whose bounding box, grown by the kernel's reach, misses the centre contribute 0
  // (a cheap per-axis test, no geometry shared with the bucketing).
  const double reach = k.type == KernelType::kBox ? 2 * half : k.ell_m;
  auto out_of_reach = [&](double lo, double hi, double c) { return c < lo - reach || c > hi + reach; };
  // Forgetting, eagerly: every scan after the first decays the cell once by lambda = 2^(-1/H)
  // (repeated multiplication, where the map takes one power per gap).
  const double lambda = forget_half_life > 0 ? std::pow(2.0, -1.0 / forget_half_life) : 1.0;
  for (const ScanObservations& s : scans) {
    if (&s != &scans.front() && forget_half_life > 0) {
      post.alpha = params.prior.alpha0 + lambda * (post.alpha - params.prior.alpha0);
      post.beta = params.prior.beta0 + lambda * (post.beta - params.prior.beta0);
    }
    for (const Vec3f& h : s.hits) {
      if (out_of_reach(h.x, h.x, center.x) || out_of_reach(h.y, h.y, center.y) || out_of_reach(h.z, h.z, center.z))
        continue;
      post.alpha += k.type == KernelType::kBox ? (in_cell(center, half, h) ? 1.0 : 0.0)
                                               : sparse_kernel(point_distance(center, h), k.ell_m, k.sigma0);
    }
    for (const Vec3f& e : s.free_ends) {
      const Vec3f& o = s.origin;
      if (out_of_reach(std::min(o.x, e.x), std::max(o.x, e.x), center.x) ||
          out_of_reach(std::min(o.y, e.y), std::max(o.y, e.y), center.y) ||
          out_of_reach(std::min(o.z, e.z), std::max(o.z, e.z), center.z))
        continue;
      post.beta += k.type == KernelType::kBox
                       ? (segment_meets_cell(center, half, s.origin, e) ? 1.0 : 0.0)
                       : sparse_kernel(segment_distance(center, s.origin, e), k.ell_m, k.sigma0);
    }
  }
  return post;
}

namespace {
// v rotated by the rotation vector r: q v q* with q = (cos(|r|/2), sin(|r|/2) r/|r|).
Vec3d rotate_by(const Vec3d& r, const Vec3d& v) {
  const double theta = std::sqrt(r.x * r.x + r.y * r.y + r.z * r.z);
  if (theta == 0) return v;
  const double w = std::cos(theta / 2), s = std::sin(theta / 2) / theta;
  const double x = s * r.x, y = s * r.y, z = s * r.z;
  // t = 2 u x v; v' = v + w t + u x t
  const double tx = 2 * (y * v.z - z * v.y), ty = 2 * (z * v.x - x * v.z), tz = 2 * (x * v.y - y * v.x);
  return {v.x + w * tx + (y * tz - z * ty), v.y + w * ty + (z * tx - x * tz), v.z + w * tz + (x * ty - y * tx)};
}

double distance_d(const Vec3d& a, const Vec3d& b) {
  return std::sqrt((a.x - b.x) * (a.x - b.x) + (a.y - b.y) * (a.y - b.y) + (a.z - b.z) * (a.z - b.z));
}

double segment_distance_d(const Vec3d& p, const Vec3d& a, const Vec3d& b) {
  const double v[3] = {b.x - a.x, b.y - a.y, b.z - a.z}, w[3] = {p.x - a.x, p.y - a.y, p.z - a.z};
  const double vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
  const double t = vv > 0 ? std::clamp((w[0] * v[0] + w[1] * v[1] + w[2] * v[2]) / vv, 0.0, 1.0) : 0.0;
  return distance_d(p, {a.x + t * v[0], a.y + t * v[1], a.z + t * v[2]});
}
}  // namespace

namespace {
// The plain counts (sum of kernels over hits, over free segments) of scan `s` displaced by `sp`
// (in double, the rotation by quaternions) at each of `centers`.
std::vector<BruteForcePosterior> displaced_counts(const std::vector<Vec3d>& centers, const ScanObservations& s,
                                                  const PoseSigmaPoint& sp, const BuildParams& params) {
  const KernelParams& k = params.kernel;
  const Vec3d o{s.origin.x, s.origin.y, s.origin.z};
  const auto moved = [&](const Vec3f& p) {
    const Vec3d r = rotate_by(sp.rotation, {p.x - o.x, p.y - o.y, p.z - o.z});
    Vec3d q{o.x + sp.translation.x + r.x, o.y + sp.translation.y + r.y, o.z + sp.translation.z + r.z};
    if (params.preprocess.planar) q.z = o.z;
    return q;
  };
  const Vec3d origin = moved(s.origin);
  std::vector<Vec3d> hits, ends;
  for (const Vec3f& h : s.hits) hits.push_back(moved(h));
  for (const Vec3f& e : s.free_ends) ends.push_back(moved(e));
  std::vector<BruteForcePosterior> counts(centers.size());
  for (size_t c = 0; c < centers.size(); ++c) {
    for (const Vec3d& h : hits) counts[c].alpha += sparse_kernel(distance_d(centers[c], h), k.ell_m, k.sigma0);
    for (const Vec3d& e : ends)
      counts[c].beta += sparse_kernel(segment_distance_d(centers[c], origin, e), k.ell_m, k.sigma0);
  }
  return counts;
}

std::vector<PoseSigmaPoint> points_or_identity(const PoseCovariance& c) {
  std::vector<PoseSigmaPoint> points = pose_sigma_points(c);
  if (points.empty()) points.push_back({1.0, {}, {}});
  return points;
}
}  // namespace

std::vector<BruteForcePosterior> brute_force_expected_cells(const std::vector<Vec3d>& centers,
                                                            const std::vector<ScanObservations>& scans,
                                                            const std::vector<PoseCovariance>& covariances,
                                                            const BuildParams& params) {
  std::vector<BruteForcePosterior> post(centers.size(), BruteForcePosterior{params.prior.alpha0, params.prior.beta0});
  for (size_t i = 0; i < scans.size(); ++i) {
    for (const PoseSigmaPoint& sp : points_or_identity(covariances[i])) {
      const std::vector<BruteForcePosterior> counts = displaced_counts(centers, scans[i], sp, params);
      const double w = sp.weight * scans[i].kernel_weight;
      for (size_t c = 0; c < centers.size(); ++c) {
        post[c].alpha += w * counts[c].alpha;
        post[c].beta += w * counts[c].beta;
      }
    }
  }
  return post;
}

std::vector<BruteForcePosterior> brute_force_expected_submap_cells(const std::vector<Vec3d>& centers,
                                                                   const std::vector<ScanObservations>& scans,
                                                                   const std::vector<PoseCovariance>& covariances,
                                                                   const BuildParams& params) {
  const double a0 = params.prior.alpha0, b0 = params.prior.beta0;
  std::vector<BruteForcePosterior> post(centers.size(), BruteForcePosterior{a0, b0});
  for (size_t i = 0; i < scans.size(); ++i) {
    // Raw moments E[p], E[p^2] of the mixture, and whether any hypothesis reached the cell.
    std::vector<double> m1(centers.size(), 0.0), m2(centers.size(), 0.0);
    std::vector<bool> seen(centers.size(), false);
    for (const PoseSigmaPoint& sp : points_or_identity(covariances[i])) {
      const std::vector<BruteForcePosterior> counts = displaced_counts(centers, scans[i], sp, params);
      for (size_t c = 0; c < centers.size(); ++c) {
        const double a = a0 + counts[c].alpha, b = b0 + counts[c].beta;
        m1[c] += sp.weight * a / (a + b);
        m2[c] += sp.weight * a * (a + 1) / ((a + b) * (a + b + 1));
        seen[c] = seen[c] || counts[c].alpha > 0 || counts[c].beta > 0;
      }
    }
    for (size_t c = 0; c < centers.size(); ++c) {
      if (!seen[c]) continue;
      // Beta(a, b) has E[p] = a / s, E[p^2] = a (a + 1) / (s (s + 1)), s = a + b; solved for s.
      const double s = (m1[c] - m2[c]) / (m2[c] - m1[c] * m1[c]);
      post[c].alpha += std::max(0.0, m1[c] * s - a0);
      post[c].beta += std::max(0.0, (1 - m1[c]) * s - b0);
    }
  }
  return post;
}

}  // namespace bgkmap
