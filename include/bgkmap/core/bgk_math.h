/* BGK math shared by the C++ back ends and the OpenCL kernels (the OpenCL kernels in kernels/ include this file).
 *
 * Written in the common subset of C++17 and OpenCL C 1.2 so that the CPU and device paths
 * evaluate exactly the same expressions: plain floats, no vector types, no references.
 * Keep it that way: every function here must compile in both languages. */
#ifndef BGKMAP_CORE_BGK_MATH_H
#define BGKMAP_CORE_BGK_MATH_H

#ifdef __OPENCL_C_VERSION__
#define BGK_FN inline
#define BGK_COS(x) cos(x)
#define BGK_SIN(x) sin(x)
#define BGK_SQRT(x) sqrt(x)
#else
#include <cmath>
#define BGK_FN inline
#define BGK_COS(x) std::cos(x)
#define BGK_SIN(x) std::sin(x)
#define BGK_SQRT(x) std::sqrt(x)
#endif

#define BGK_TWO_PI_F 6.28318530717958647692f

/* Kernel selector values, shared with the host's KernelType enum. */
#define BGK_KERNEL_SPARSE 0
#define BGK_KERNEL_BOX 1

/* Sparse kernel of Melkumyan & Ramos at distance d (metres) for length scale ell and scale sigma0:
 *   k(d) = sigma0 [(2 + cos(2 pi d/ell))/3 (1 - d/ell) + sin(2 pi d/ell)/(2 pi)] for d < ell, else 0.
 * Zero at and beyond ell, sigma0 at d = 0, monotone decreasing and C1 at ell.
 *
 * Near ell the two terms cancel to O(u^5), u = 1 - d/ell, and evaluating them as written in float
 * leaves noise of ~1e-8 sigma0 that is neither monotone nor small relative to the tiny prior.
 * There the series in x = 2 pi u is used instead (error < 1e-9 relative for u <= 1/4):
 *   k = sigma0 u sum_{n>=2} (-1)^n x^(2n) (2n - 2) / (3 (2n + 1)!). */
BGK_FN float bgk_sparse_kernel(float d, float ell, float sigma0) {
  if (d >= ell) return 0.0f;
  const float r = d / ell;
  const float u = 1.0f - r;
  if (u <= 0.25f) {
    const float x = BGK_TWO_PI_F * u;
    const float x2 = x * x;
    const float series =  /* Horner form of the series above, terms n = 2..7 */
        x2 * x2 * (1.0f / 180.0f + x2 * (-1.0f / 3780.0f + x2 * (1.0f / 181440.0f + x2 * (-1.0f / 14968800.0f + x2 * (1.0f / 1868106240.0f + x2 * (-1.0f / 326918592000.0f))))));
    return sigma0 * u * series;
  }
  const float a = BGK_TWO_PI_F * r;
  return sigma0 * ((2.0f + BGK_COS(a)) * (1.0f / 3.0f) * u + BGK_SIN(a) * (1.0f / BGK_TWO_PI_F));
}

/* Same, from a squared distance; callers skip pairs with d2 >= ell2 before paying for sqrt. */
BGK_FN float bgk_sparse_kernel_d2(float d2, float ell, float sigma0) {
  return bgk_sparse_kernel(BGK_SQRT(d2), ell, sigma0);
}

/* Squared distance from point p to the segment a->b, projection clamped to the segment.
 * A zero-length segment (a == b) is the point a. */
BGK_FN float bgk_point_segment_dist2(float px, float py, float pz,
                                     float ax, float ay, float az,
                                     float bx, float by, float bz) {
  const float vx = bx - ax, vy = by - ay, vz = bz - az;
  const float wx = px - ax, wy = py - ay, wz = pz - az;
  const float vv = vx * vx + vy * vy + vz * vz;
  float t = 0.0f;
  if (vv > 0.0f) {
    t = (wx * vx + wy * vy + wz * vz) / vv;
    t = t < 0.0f ? 0.0f : (t > 1.0f ? 1.0f : t);
  }
  const float dx = wx - t * vx, dy = wy - t * vy, dz = wz - t * vz;
  return dx * dx + dy * dy + dz * dz;
}

/* The same distance for a segment given by an anchor q (a point of the segment's line), a unit
 * direction u and the segment's extent [s_min, s_max] along u measured from q: the segment is
 * q + s u. With q chosen near the block being evaluated every quantity stays as small as a
 * block, so float rounding does not grow with the beam's length or the map's extent.
 * A zero-length segment has u = 0 and s_min = s_max = 0. */
BGK_FN float bgk_anchored_segment_dist2(float px, float py, float pz,
                                        float qx, float qy, float qz,
                                        float ux, float uy, float uz, float s_min, float s_max) {
  const float wx = px - qx, wy = py - qy, wz = pz - qz;
  float s = wx * ux + wy * uy + wz * uz;
  s = s < s_min ? s_min : (s > s_max ? s_max : s);
  const float dx = wx - s * ux, dy = wy - s * uy, dz = wz - s * uz;
  return dx * dx + dy * dy + dz * dz;
}

/* Box kernel: 1 when the point lies in the half-open cell [c - h, c + h) on every axis. */
BGK_FN float bgk_box_kernel_point(float cx, float cy, float cz, float half,
                                  float px, float py, float pz) {
  return (px >= cx - half && px < cx + half && py >= cy - half && py < cy + half &&
          pz >= cz - half && pz < cz + half) ? 1.0f : 0.0f;
}

/* Box kernel for a beam: 1 when the segment a->b passes through the closed cell box (slab test),
 * which is what the counting sensor model counts as "the beam traversed the cell". */
BGK_FN float bgk_box_kernel_segment(float cx, float cy, float cz, float half,
                                    float ax, float ay, float az,
                                    float bx, float by, float bz) {
  float t0 = 0.0f, t1 = 1.0f;
  const float o[3] = {ax, ay, az};
  const float v[3] = {bx - ax, by - ay, bz - az};
  const float lo[3] = {cx - half, cy - half, cz - half};
  const float hi[3] = {cx + half, cy + half, cz + half};
  for (int i = 0; i < 3; ++i) {
    if (v[i] == 0.0f) {
      if (o[i] < lo[i] || o[i] > hi[i]) return 0.0f;
    } else {
      float ta = (lo[i] - o[i]) / v[i];
      float tb = (hi[i] - o[i]) / v[i];
      if (ta > tb) { const float tmp = ta; ta = tb; tb = tmp; }
      t0 = ta > t0 ? ta : t0;
      t1 = tb < t1 ? tb : t1;
      if (t0 > t1) return 0.0f;
    }
  }
  return 1.0f;
}

#endif /* BGKMAP_CORE_BGK_MATH_H */
