/* BGK math shared by the C++ back ends and the OpenCL kernels (the OpenCL kernels in kernels/ include this file).
 *
 * Written in the common subset of C++17 and OpenCL C 1.2 so that the CPU and device paths
 * evaluate exactly the same expressions: plain floats, no vector types, no references.
 * Keep it that way: every function here must compile in both languages (and avoid OpenCL C's
 * reserved words as names: `half` is a type there). */
#ifndef BGKMAP_CORE_BGK_MATH_H
#define BGKMAP_CORE_BGK_MATH_H

#ifdef __OPENCL_C_VERSION__
#define BGK_FN inline
#define BGK_SQRT(x) sqrt(x)
#define BGK_FLOOR(x) floor(x)
#else
#include <cmath>
#define BGK_FN inline
#define BGK_SQRT(x) std::sqrt(x)
#define BGK_FLOOR(x) std::floor(x)
#endif

#define BGK_TWO_PI_F 6.28318530717958647692f

/* Kernel selector values, shared with the host's KernelType enum. */
#define BGK_KERNEL_SPARSE 0
#define BGK_KERNEL_BOX 1

/* Sparse kernel of Melkumyan & Ramos at distance d (metres) for length scale ell and scale sigma0,
 * here as a function of r = d / ell:
 *   k(d) = sigma0 [(2 + cos(2 pi r))/3 (1 - r) + sin(2 pi r)/(2 pi)],  r = d/ell < 1;  0 beyond.
 * Zero at and beyond ell, sigma0 at d = 0, monotone decreasing and C1 at ell.
 *
 * Evaluated without libm so that it is cheap, vectorizes on the CPU and gives the same float
 * expressions on every OpenCL device (docs/ALGORITHM.md, "Kernels"):
 * - u = 1 - r <= 0.4: the closed form cancels to O(u^5) there, so the series
 *     k = sigma0 u sum_{n>=2} (-1)^n x^(2n) (2n - 2) / (3 (2n + 1)!),  x = 2 pi u,
 *   is summed for n = 2..8 (truncation < 5e-9 relative);
 * - r < 0.6: the closed form with sin and cos of 2 pi r from quadrant reduction and Taylor
 *   polynomials on [-pi/4, pi/4] (truncation < 2e-9).
 * Branch-free (selects, not ifs) so that loops over cells vectorize. */
BGK_FN float bgk_sparse_kernel_of_ratio(float r, float sigma0) {
  const float u = 1.0f - r;

  const float x = BGK_TWO_PI_F * u;
  const float x2 = x * x;
  const float series =
      u * x2 * x2 *
      (1.0f / 180.0f +
       x2 * (-1.0f / 3780.0f +
             x2 * (1.0f / 181440.0f +
                   x2 * (-1.0f / 14968800.0f +
                         x2 * (1.0f / 1868106240.0f + x2 * (-1.0f / 326918592000.0f + x2 * (1.0f / 76218734592000.0f)))))));

  /* sin and cos of 2 pi r for r in [0, 0.625): r = q/4 + t, |t| <= 1/8. */
  const float q = BGK_FLOOR(4.0f * r + 0.5f);
  const float th = BGK_TWO_PI_F * (r - 0.25f * q);
  const float th2 = th * th;
  const float s = th * (1.0f + th2 * (-1.0f / 6.0f + th2 * (1.0f / 120.0f + th2 * (-1.0f / 5040.0f + th2 * (1.0f / 362880.0f)))));
  const float c = 1.0f + th2 * (-0.5f + th2 * (1.0f / 24.0f + th2 * (-1.0f / 720.0f + th2 * (1.0f / 40320.0f + th2 * (-1.0f / 3628800.0f)))));
  const float sin_2pi_r = q == 0.0f ? s : (q == 1.0f ? c : -s);
  const float cos_2pi_r = q == 0.0f ? c : (q == 1.0f ? -s : -c);
  const float closed = (2.0f + cos_2pi_r) * (1.0f / 3.0f) * u + sin_2pi_r * (1.0f / BGK_TWO_PI_F);

  const float k = sigma0 * (u <= 0.4f ? series : closed);
  return r < 1.0f ? k : 0.0f;
}

BGK_FN float bgk_sparse_kernel(float d, float ell, float sigma0) { return bgk_sparse_kernel_of_ratio(d / ell, sigma0); }

/* Same, from a squared distance and 1 / ell^2 (KernelParams::inverse_ell_squared(), one float
 * for every back end): r = sqrt(d2 / ell^2) without a division per pair. */
BGK_FN float bgk_sparse_kernel_d2(float d2, float inv_ell2, float sigma0) {
  return bgk_sparse_kernel_of_ratio(BGK_SQRT(d2 * inv_ell2), sigma0);
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
BGK_FN float bgk_box_kernel_point(float cx, float cy, float cz, float half_size,
                                  float px, float py, float pz) {
  return (px >= cx - half_size && px < cx + half_size && py >= cy - half_size && py < cy + half_size &&
          pz >= cz - half_size && pz < cz + half_size) ? 1.0f : 0.0f;
}

/* Box kernel for a beam: 1 when the segment a->b passes through the closed cell box (slab test),
 * which is what the counting sensor model counts as "the beam traversed the cell". */
BGK_FN float bgk_box_kernel_segment(float cx, float cy, float cz, float half_size,
                                    float ax, float ay, float az,
                                    float bx, float by, float bz) {
  float t0 = 0.0f, t1 = 1.0f;
  const float o[3] = {ax, ay, az};
  const float v[3] = {bx - ax, by - ay, bz - az};
  const float lo[3] = {cx - half_size, cy - half_size, cz - half_size};
  const float hi[3] = {cx + half_size, cy + half_size, cz + half_size};
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
