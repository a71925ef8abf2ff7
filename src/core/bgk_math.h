/* BGK math shared by the C++ back ends and the OpenCL kernels (the OpenCL kernels in kernels/ include this file).
 *
 * Written in the common subset of C++17 and OpenCL C 1.2 so that the CPU and device paths
 * evaluate exactly the same expressions: plain floats, no vector types, no references.
 * Keep it that way: every function here must compile in both languages (and avoid OpenCL C's
 * reserved words as names: `half` is a type there). */
#ifndef BGKMAP_CORE_BGK_MATH_H
#define BGKMAP_CORE_BGK_MATH_H

/* BGK_FMA is a fused multiply-add, rounded once: the same value on every CPU clone (hardware FMA
 * on AVX2/AVX-512 machines, libm's correctly rounded fmaf elsewhere) and every OpenCL device
 * (fma() is correctly rounded in OpenCL C), so the back ends keep computing identical floats.
 * The library builds with -ffp-contract=off and the kernels with FP_CONTRACT OFF: only these
 * explicit fusions happen. */
#ifdef __OPENCL_C_VERSION__
#define BGK_FN inline
#define BGK_SQRT(x) sqrt(x)
#define BGK_FMA(a, b, c) fma(a, b, c)
#else
#include <cmath>
#define BGK_FN inline
#define BGK_SQRT(x) std::sqrt(x)
#define BGK_FMA(a, b, c) std::fma(a, b, c)
#endif

/* Kernel selector values, shared with the host's KernelType enum. */
#define BGK_KERNEL_SPARSE 0
#define BGK_KERNEL_BOX 1

/* Sparse kernel of Melkumyan & Ramos at distance d (metres) for length scale ell and scale sigma0,
 * here as a function of r = d / ell:
 *   k(d) = sigma0 [(2 + cos(2 pi r))/3 (1 - r) + sin(2 pi r)/(2 pi)],  r = d/ell < 1;  0 beyond.
 * Zero at and beyond ell, sigma0 at d = 0, monotone decreasing and C1 at ell.
 *
 * Evaluated without libm, in one polynomial, so that it is cheap, vectorizes on the CPU and gives
 * the same float expressions on every OpenCL device (docs/ALGORITHM.md, "Kernels"). With
 * u = 1 - r the kernel vanishes to fifth order at r = 1, and k / (sigma0 u^5) is an entire
 * function of u^2 (the series sum_{n>=2} (-1)^n (2 pi)^(2n) u^(2n-4) (2n - 2) / (3 (2n + 1)!)),
 * so k = sigma0 u^5 P(2 u^2 - 1) with P its degree-7 Chebyshev-Lobatto interpolant on
 * u^2 in [0, 1] (scripts/fit_sparse_kernel.py prints the coefficients and the error): within
 * 5e-7 relative of the closed form in double over the whole support, exactly sigma0 at d = 0,
 * exactly 0 at d = ell, and the relative accuracy holds near ell where the closed form cancels.
 *
 * The per-pair functions are written once, for a float type T and a name suffix: float (no
 * suffix) on every back end, and float16 (suffix _16) in the OpenCL kernel that evaluates two rows
 * of an 8^3 block per work-item on CPU devices. Every operation acts per lane, so each lane rounds
 * exactly as the float version does (constants are cast to T: OpenCL's fma does not widen
 * scalars, and a vector condition in ?: selects per lane between operands of type T). */
/* P's coefficients, in powers of t = 2 u^2 - 1 (scripts/fit_sparse_kernel.py); the CPU back end's
 * AVX-512 beam loop evaluates the same polynomial with them. */
#define BGK_SPARSE_P0 3.17947674f
#define BGK_SPARSE_P1 -3.40534735f
#define BGK_SPARSE_P2 1.57820821f
#define BGK_SPARSE_P3 -0.415403873f
#define BGK_SPARSE_P4 0.0708464682f
#define BGK_SPARSE_P5 -0.00848962367f
#define BGK_SPARSE_P6 0.00076154212f
#define BGK_SPARSE_P7 -5.21756992e-05f

#define BGK_DEFINE_PAIR_MATH(T, SUFFIX)                                                            \
  BGK_FN T bgk_sparse_kernel_of_ratio##SUFFIX(T r, float sigma0) {                                \
    const T u = 1.0f - r;                                                                          \
    const T v = u * u;                                                                             \
    const T t = BGK_FMA((T)(2.0f), v, (T)(-1.0f));                                                 \
    /* Estrin's scheme: four independent pairs, then two levels, so the dependency chain is three  \
     * fused steps deep instead of Horner's seven (the pair loops are latency bound). */           \
    const T t2 = t * t;                                                                            \
    const T t4 = t2 * t2;                                                                          \
    const T p01 = BGK_FMA(t, (T)(BGK_SPARSE_P1), (T)(BGK_SPARSE_P0));                              \
    const T p23 = BGK_FMA(t, (T)(BGK_SPARSE_P3), (T)(BGK_SPARSE_P2));                              \
    const T p45 = BGK_FMA(t, (T)(BGK_SPARSE_P5), (T)(BGK_SPARSE_P4));                              \
    const T p67 = BGK_FMA(t, (T)(BGK_SPARSE_P7), (T)(BGK_SPARSE_P6));                              \
    const T p = BGK_FMA(t4, BGK_FMA(t2, p67, p45), BGK_FMA(t2, p23, p01));                         \
    const T k = sigma0 * ((v * v) * u * p);                                                        \
    return r < 1.0f ? k : (T)(0.0f);                                                               \
  }                                                                                                \
                                                                                                   \
  /* Same, from a squared distance and 1 / ell^2 (KernelParams::inverse_ell_squared(), one float  \
   * for every back end): r = sqrt(d2 / ell^2) without a division per pair. */                     \
  BGK_FN T bgk_sparse_kernel_d2##SUFFIX(T d2, float inv_ell2, float sigma0) {                      \
    return bgk_sparse_kernel_of_ratio##SUFFIX(BGK_SQRT(d2 * inv_ell2), sigma0);                    \
  }                                                                                                \
                                                                                                   \
  /* The squared distance from a point to a segment, from the point's offset w = p - q from the    \
   * segment's anchor (see bgk_anchored_segment_dist2 below). Two one-sided clamps of the          \
   * projection (s_min <= s_max, so the same value as the nested choice): each is one max or min   \
   * instruction on the CPU, fewer than the nested form compiles to. */                            \
  BGK_FN T bgk_offset_segment_dist2##SUFFIX(T wx, T wy, T wz, float ux, float uy, float uz, float s_min, \
                                            float s_max) {                                         \
    T s = BGK_FMA(wx, (T)(ux), BGK_FMA(wy, (T)(uy), wz * uz));                                     \
    s = s < s_min ? (T)(s_min) : s;                                                                \
    s = s > s_max ? (T)(s_max) : s;                                                                \
    const T dx = BGK_FMA(-s, (T)(ux), wx), dy = BGK_FMA(-s, (T)(uy), wy), dz = BGK_FMA(-s, (T)(uz), wz); \
    return BGK_FMA(dx, dx, BGK_FMA(dy, dy, dz * dz));                                              \
  }

BGK_DEFINE_PAIR_MATH(float, )
#ifdef __OPENCL_C_VERSION__
BGK_DEFINE_PAIR_MATH(float16, _16)
#endif

BGK_FN float bgk_sparse_kernel(float d, float ell, float sigma0) { return bgk_sparse_kernel_of_ratio(d / ell, sigma0); }

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

/* The squared distance from a point to a segment given by an anchor q (a point of the segment's
 * line), a unit direction u and the segment's extent [s_min, s_max] along u measured from q: the
 * segment is q + s u. With q chosen near the block being evaluated every quantity stays as small as a
 * block, so float rounding does not grow with the beam's length or the map's extent.
 * A zero-length segment has u = 0 and s_min = s_max = 0.
 * bgk_offset_segment_dist2 above takes the point's offset w = p - q from the anchor (the CPU back
 * end computes the offsets of a block's cells once per beam); this form takes p itself. */
BGK_FN float bgk_anchored_segment_dist2(float px, float py, float pz,
                                        float qx, float qy, float qz,
                                        float ux, float uy, float uz, float s_min, float s_max) {
  return bgk_offset_segment_dist2(px - qx, py - qy, pz - qz, ux, uy, uz, s_min, s_max);
}

/* Box kernel: 1 when the point lies in the half-open cell [c - h, c + h) on every axis. */
BGK_FN float bgk_box_kernel_point(float cx, float cy, float cz, float half_size,
                                  float px, float py, float pz) {
  return (px >= cx - half_size && px < cx + half_size && py >= cy - half_size && py < cy + half_size &&
          pz >= cz - half_size && pz < cz + half_size) ? 1.0f : 0.0f;
}

/* Narrows [*s0, *s1] to the parameters s where q + s u lies within [lo, hi] (one axis of a
 * segment q + s u against a slab); false when nothing is left. The culling of the CPU loops, the
 * kernels' per-block beam reach and the box kernel's segment test all clip with it. */
BGK_FN bool bgk_clip_to_slab(float q, float u, float lo, float hi, float* s0, float* s1) {
  if (u == 0.0f) return q >= lo && q <= hi;
  float ta = (lo - q) / u, tb = (hi - q) / u;
  if (ta > tb) {
    const float tmp = ta;
    ta = tb;
    tb = tmp;
  }
  *s0 = ta > *s0 ? ta : *s0;
  *s1 = tb < *s1 ? tb : *s1;
  return *s0 <= *s1;
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
  for (int i = 0; i < 3; ++i)
    if (!bgk_clip_to_slab(o[i], v[i], lo[i], hi[i], &t0, &t1)) return 0.0f;
  return 1.0f;
}

/* Forgetting (map/forgetting.hpp): a count moved toward its prior by `factor` = lambda^dt, one
 * rounding after the subtraction, the same on the host and on every device. */
BGK_FN float bgk_decayed(float value, float prior, float factor) { return BGK_FMA(factor, value - prior, prior); }

#endif /* BGKMAP_CORE_BGK_MATH_H */
