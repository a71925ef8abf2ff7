// Which rows of an 8^3 block a beam can reach: one bit per row, shared by the CPU back end (which
// evaluates the rows with bits, two at a time) and the OpenCL back end's host side (which gives
// the kernel the bits). Private to the library.
//
// A row (all x, fixed y and z) is flagged when some point of its x-range, cut to the x-extent of
// the segment grown by reach, lies within reach of the beam's line: a superset of the rows with a
// cell within reach of the segment. The reach is padded so that float rounding never drops a row
// with a cell within l (the kernel itself decides exactly, and gives 0 beyond l), so skipping the
// other rows changes which pairs are computed, never a sum.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "bgkmap/integrate/bucketing.hpp"
#include "integrate/cpu/cpu_clones.hpp"

namespace bgkmap {

constexpr int kRows8 = 64;  // rows i = z * 8 + y

// The padded reach of the row bits for cells of `resolution_m` and length scale `ell`.
struct RowReach8 {
  float res;
  float row_reach, row_reach2;  // ell padded, and its square padded further
  float cell_pad;               // in cell units
  uint64_t layer_rows = ~uint64_t{0};  // the rows that may be flagged at all: a planar map's layer
  static RowReach8 make(double resolution_m, float ell) {
    RowReach8 g;
    g.res = static_cast<float>(resolution_m);
    g.row_reach = ell * (1.0f + 1e-3f);
    const float span = 8.0f * g.res + g.row_reach;  // the largest distances in the row test
    g.row_reach2 = g.row_reach * g.row_reach + 1e-5f * span * span;
    g.cell_pad = 1e-3f;
    return g;
  }
};

// Along row (y, z), the row point (qx + a, y, z) has squared distance to the beam's line minus
// reach^2 of A a^2 - 2 h a + c, with A = 1 - ux^2, h = ux e, c = wy^2 + wz^2 - e^2 - reach^2,
// w = (y, z) - (qy, qz), e = wy uy + wz uz: a convex function of a, least at a = h / A. A beam
// exactly along x (A = 0) takes A = 1e-20: its rows are then all in or all out.

// 64 flag bytes (0 or 1) as one bit mask, bit i for byte i. Eight bytes become eight bits with
// one multiply: byte k lands on bit 56 + k.
BGK_INLINE_INTO_CLONES uint64_t pack_row_flags_8(const uint8_t* flags) {
  uint64_t rows = 0;
  for (int w = 0; w < kRows8; w += 8) {
    uint64_t word;
    std::memcpy(&word, flags + w, sizeof word);
    rows |= ((word * 0x0102040810204080ull) >> 56) << w;
  }
  return rows;
}

// A of the quadratic above, kept from zero.
BGK_INLINE_INTO_CLONES float along_x_of(const LocalBeam& b) { return std::max(1.0f - b.ux * b.ux, 1e-20f); }

// h and c of the quadratic above for row i.
struct RowQuadratic {
  float h, c;
};
BGK_INLINE_INTO_CLONES RowQuadratic row_quadratic_8(const RowReach8& g, const LocalBeam& b, int i) {
  const float wy = (i & 7) * g.res - b.qy, wz = (i >> 3) * g.res - b.qz;
  const float e = wy * b.uy + wz * b.uz;
  return {b.ux * e, wy * wy + wz * wz - e * e - g.row_reach2};
}

// The range of a = x - qx the row test looks at: the rows' x-range [0, 7 res] cut to the segment's
// x-extent grown by reach, padded by cell_pad cells. False when it is empty (no row is reached).
BGK_INLINE_INTO_CLONES bool row_test_range_8(const RowReach8& g, const LocalBeam& b, float& a_lo, float& a_hi) {
  const float xa = b.qx + b.s_min * b.ux, xb = b.qx + b.s_max * b.ux;
  const float pad = g.cell_pad * g.res;
  const float x_lo = std::max(std::min(xa, xb) - g.row_reach, 0.0f) - pad;
  const float x_hi = std::min(std::max(xa, xb) + g.row_reach, 7.0f * g.res) + pad;
  if (!(x_lo <= x_hi)) return false;
  a_lo = x_lo - b.qx;
  a_hi = x_hi - b.qx;
  return true;
}

// The rows a beam can reach: bit i is set when some point of row i's x-range, cut to the
// segment's x-extent grown by reach (padded by cell_pad cells), lies within reach of the beam's
// line: f(a) above at a = h / A clamped to that range is <= 0. No square root, no rounding to
// cells.
BGK_INLINE_INTO_CLONES uint64_t beam_row_mask_8(const RowReach8& g, const LocalBeam& b) {
  float a_lo, a_hi;
  if (!row_test_range_8(g, b, a_lo, a_hi)) return 0;
  const float along_x = along_x_of(b);
  const float inv_along_x = 1.0f / along_x;
  alignas(64) uint8_t near[kRows8];
#pragma omp simd
  for (int i = 0; i < kRows8; ++i) {
    const RowQuadratic q = row_quadratic_8(g, b, i);
    float a = q.h * inv_along_x;
    a = a < a_lo ? a_lo : (a > a_hi ? a_hi : a);
    near[i] = (along_x * a - 2.0f * q.h) * a + q.c <= 0.0f;
  }
  return pack_row_flags_8(near) & g.layer_rows;
}

#if BGK_AVX512_BEAMS
// Whether this CPU runs the BGK_TARGET_AVX512 functions (it has x86-64-v4's instructions). They
// inline only into functions compiled for that target as well.
bool cpu_runs_avx512_beams();

// beam_row_mask_8 with AVX-512 intrinsics: the same float operations on the same values in the
// same order (so the same bits), but each 16 rows' test lands in a compare mask directly (the
// portable loop spent about 40 instructions packing flag bytes) and the y terms, the same for
// each 16 rows (y = lane & 7), are computed once.
BGK_TARGET_AVX512 [[gnu::always_inline]] inline uint64_t beam_row_mask_8_avx512(const RowReach8& g,
                                                                            const LocalBeam& b) {
  float range_lo, range_hi;
  if (!row_test_range_8(g, b, range_lo, range_hi)) return 0;
  const float along_x = along_x_of(b);
  const __m512 a_lo = _mm512_set1_ps(range_lo), a_hi = _mm512_set1_ps(range_hi);
  const __m512 inv_along_x = _mm512_set1_ps(1.0f / along_x), along = _mm512_set1_ps(along_x);
  const __m512 res = _mm512_set1_ps(g.res), ux = _mm512_set1_ps(b.ux), uy = _mm512_set1_ps(b.uy);
  const __m512 uz = _mm512_set1_ps(b.uz), qz = _mm512_set1_ps(b.qz), reach2 = _mm512_set1_ps(g.row_reach2);
  // (The maskz forms: GCC 12 warns about the plain ones' undefined pass-through operand.)
  const __mmask16 kAll = 0xFFFF;
  const __m512i lane = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  const __m512 cell_y = _mm512_maskz_cvtepi32_ps(kAll, _mm512_and_si512(lane, _mm512_set1_epi32(7)));
  const __m512 wy = _mm512_sub_ps(_mm512_mul_ps(cell_y, res), _mm512_set1_ps(b.qy));
  const __m512 wy_uy = _mm512_mul_ps(wy, uy), wy2 = _mm512_mul_ps(wy, wy);
  uint64_t rows = 0;
  for (int k = 0; k < 4; ++k) {  // rows 16 k .. 16 k + 15: z = 2 k + (lane >> 3)
    const __m512i z = _mm512_add_epi32(_mm512_srli_epi32(lane, 3), _mm512_set1_epi32(2 * k));
    const __m512 cell_z = _mm512_maskz_cvtepi32_ps(kAll, z);
    const __m512 wz = _mm512_sub_ps(_mm512_mul_ps(cell_z, res), qz);
    const __m512 e = _mm512_add_ps(wy_uy, _mm512_mul_ps(wz, uz));
    const __m512 h = _mm512_mul_ps(ux, e);
    const __m512 c =
        _mm512_sub_ps(_mm512_sub_ps(_mm512_add_ps(wy2, _mm512_mul_ps(wz, wz)), _mm512_mul_ps(e, e)), reach2);
    // a < a_lo ? a_lo : a, then a > a_hi ? a_hi : a (vmaxps/vminps return their second operand
    // unless the first is strictly greater/less).
    __m512 a = _mm512_mul_ps(h, inv_along_x);
    a = _mm512_maskz_min_ps(kAll, a_hi, _mm512_maskz_max_ps(kAll, a_lo, a));
    const __m512 two_h = _mm512_mul_ps(_mm512_set1_ps(2.0f), h);
    const __m512 f = _mm512_add_ps(_mm512_mul_ps(_mm512_sub_ps(_mm512_mul_ps(along, a), two_h), a), c);
    rows |= static_cast<uint64_t>(_mm512_cmp_ps_mask(f, _mm512_setzero_ps(), _CMP_LE_OQ)) << (16 * k);
  }
  return rows & g.layer_rows;
}
#endif

// beam_row_mask_8 for `count` beams (with beam_row_mask_8_avx512 where the CPU runs it: the same
// bits).
void beam_row_masks_8(const RowReach8& g, const LocalBeam* beams, size_t count, uint64_t* masks);

}  // namespace bgkmap
