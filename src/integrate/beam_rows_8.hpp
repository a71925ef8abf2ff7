// Which cells of an 8^3 block a beam can reach, row by row: shared by the CPU back end (which
// lists the cells of the rows' intervals) and the OpenCL back end's host side (which gives the
// kernel one bit per row). Private to the library.
//
// Each row (all x, fixed y and z) meets the cylinder of radius reach around the beam's line in one
// interval of x; cut to the x-extent of the segment grown by reach, it holds every cell of the row
// within reach of the segment. The intervals are padded so that float rounding never drops a cell
// within l (the kernel itself decides exactly), so skipping the cells outside them changes which
// pairs are computed, never a sum.
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

// The padded reach of the row intervals for cells of `resolution_m` and length scale `ell`.
struct RowReach8 {
  float res, inv_res;
  float row_reach, row_reach2;  // ell padded, and its square padded further
  float cell_pad;               // in cell units
  static RowReach8 make(double resolution_m, float ell) {
    RowReach8 g;
    g.res = static_cast<float>(resolution_m);
    g.inv_res = static_cast<float>(1.0 / resolution_m);
    g.row_reach = ell * (1.0f + 1e-3f);
    const float span = 8.0f * g.res + g.row_reach;  // the largest distances in the row intervals
    g.row_reach2 = g.row_reach * g.row_reach + 1e-5f * span * span;
    g.cell_pad = 1e-3f;
    return g;
  }
};

// Each row's cells within its interval: the row meets the cylinder in one x-interval, cut to
// [x_min, x_max] (cell units).
// For the row point (qx + a, y, z) the squared distance to the line minus reach^2 is
// A a^2 - 2 h a + c, with A = 1 - ux^2, h = ux e, c = wy^2 + wz^2 - e^2 - reach^2,
// w = (y, z) - (qy, qz), e = wy uy + wz uz; the row meets the cylinder when h^2 - A c >= 0.
// kSteep: A >= kSteepAlongX, the roots (h -+ sqrt(h^2 - A c)) / A lose at most ten ulps of the
// block-sized h to cancellation, far less than cell_pad. Otherwise the stable form q / A and
// c / q, q = h + sign(h) sqrt(h^2 - A c), costs a division; a beam exactly along x (A = 0) takes
// A = 1e-20: a row is then all in (c <= 0, roots far outside the block) or all out. (Written so
// that it vectorizes: no bools between statements, no std::min/max on references.)
constexpr float kSteepAlongX = 0.1f;

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

template <bool kSteep>
BGK_INLINE_INTO_CLONES void row_intervals_8(const RowReach8& g, const LocalBeam& b, float x_min, float x_max,
                                            int32_t* first, int32_t* count, uint8_t* nonempty) {
  const float along_x = along_x_of(b);
  const float inv_along_x = 1.0f / along_x;
#pragma omp simd
  for (int i = 0; i < kRows8; ++i) {
    const RowQuadratic q_row = row_quadratic_8(g, b, i);
    const float h = q_row.h, c = q_row.c;
    const float disc = h * h - along_x * c;
    const float root = std::sqrt(disc > 0.0f ? disc : 0.0f);
    float r_lo, r_hi;
    if (kSteep) {
      r_lo = (h - root) * inv_along_x;
      r_hi = (h + root) * inv_along_x;
    } else {
      const float q = h >= 0.0f ? h + root : h - root;
      const float r1 = q * inv_along_x, r2 = q != 0.0f ? c / q : 0.0f;
      r_lo = r1 < r2 ? r1 : r2;
      r_hi = r1 < r2 ? r2 : r1;
    }
    float lo = (r_lo + b.qx) * g.inv_res - g.cell_pad, hi = (r_hi + b.qx) * g.inv_res + g.cell_pad;
    lo = lo < x_min ? x_min : lo;
    hi = hi > x_max ? x_max : hi;
    const int from = static_cast<int>(std::ceil(lo)), to = static_cast<int>(std::floor(hi));
    const int row_first = from < 0 ? 0 : from;
    const int n = (to > 7 ? 7 : to) - row_first + 1;
    first[i] = row_first;
    count[i] = disc >= 0.0f && n > 0 ? n : 0;
    nonempty[i] = count[i] > 0;
  }
}

// The intervals of the segment q + s u, s in [s_min, s_max] (row i's cells are first[i] ..
// first[i] + count[i] - 1), and the rows with cells as one bit mask (bit i: row i). The rows'
// intervals are cut to the segment's x-extent grown by reach (what matters where the segment
// ends near the block; the anchor q lies near the block, so the ends' coordinates are small or far
// outside it).
// The same intervals without the mask (nonempty[i]: 1 when row i has cells).
BGK_INLINE_INTO_CLONES void beam_row_intervals_8(const RowReach8& g, const LocalBeam& b, int32_t* first, int32_t* count,
                                                 uint8_t* nonempty) {
  const float xa = b.qx + b.s_min * b.ux, xb = b.qx + b.s_max * b.ux;
  // Bounds in cell units, kept within one cell of the block so that the conversions stay small.
  const float x_min = std::max((std::min(xa, xb) - g.row_reach) * g.inv_res - g.cell_pad, -1.0f);
  const float x_max = std::min((std::max(xa, xb) + g.row_reach) * g.inv_res + g.cell_pad, 8.0f);
  if (along_x_of(b) >= kSteepAlongX)
    row_intervals_8<true>(g, b, x_min, x_max, first, count, nonempty);
  else
    row_intervals_8<false>(g, b, x_min, x_max, first, count, nonempty);
}

BGK_INLINE_INTO_CLONES uint64_t beam_rows_8(const RowReach8& g, const LocalBeam& b, int32_t* first, int32_t* count) {
  alignas(64) uint8_t nonempty[kRows8];
  beam_row_intervals_8(g, b, first, count, nonempty);
  return pack_row_flags_8(nonempty);
}

// The rows that can hold a cell within reach of the segment, without their intervals (for the
// OpenCL kernels, which test a row's bit and then evaluate the whole row): bit i is set when some
// point of row i's x-range, cut to the segment's x-extent grown by reach, lies within reach of
// the beam's line. With a = x - qx, the squared distance to the line minus reach^2 along the row
// is the convex f(a) = A a^2 - 2 h a + c above, least at a = h / A clamped to the range: no square
// root, no rounding to cells, so it costs a fraction of row_intervals_8, and its bits are a
// superset of the rows with cells there (the cell range is padded by cell_pad as there).
BGK_INLINE_INTO_CLONES uint64_t beam_row_mask_8(const RowReach8& g, const LocalBeam& b) {
  const float xa = b.qx + b.s_min * b.ux, xb = b.qx + b.s_max * b.ux;
  const float pad = g.cell_pad * g.res;
  const float x_lo = std::max(std::min(xa, xb) - g.row_reach, 0.0f) - pad;
  const float x_hi = std::min(std::max(xa, xb) + g.row_reach, 7.0f * g.res) + pad;
  if (!(x_lo <= x_hi)) return 0;
  const float a_lo = x_lo - b.qx, a_hi = x_hi - b.qx;
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
  return pack_row_flags_8(near);
}

// The cells of 8^3 blocks, z * 64 + y * 8 + x; kCells8 is the CPU back end's spare slot.
constexpr int kCells8 = 512;

// The cells of the rows' intervals for the segment q + s u, s in [s_min, s_max], row by row and
// x ascending: writes their indices to `cells`, which has room for kCells8 + 16 entries (the 16
// after the last are set to kCells8), and returns their count.
BGK_INLINE_INTO_CLONES int beam_cells_8(const RowReach8& g, const LocalBeam& b, int32_t* cells) {
  alignas(64) int32_t first[kRows8], count[kRows8];
  // The rows with cells (about a third of them) as one bit mask, so that one loop visits them
  // (a loop per word of flags cost a mispredicted exit each).
  uint64_t rows = beam_rows_8(g, b, first, count);
  int total = 0;
  for (; rows != 0; rows &= rows - 1) {
    const int i = __builtin_ctzll(rows);
    const int32_t base = i * 8 + first[i];
#pragma omp simd
    for (int j = 0; j < 8; ++j) cells[total + j] = base + j;
    total += count[i];
  }
#pragma omp simd
  for (int j = 0; j < 16; ++j) cells[total + j] = kCells8;
  return total;
}

#if BGK_AVX512_BEAMS
// Whether this CPU runs the BGK_TARGET_AVX512 functions (it has x86-64-v4's instructions). They
// inline only into functions compiled for that target as well.
bool cpu_runs_avx512_beams();

// beam_cells_8 with AVX-512: each row's cells as an 8-bit mask, two rows' as one 16-bit mask, and
// each pair of rows with cells compressed into the list in one step, in the same order (row by
// row, x ascending), so the sums do not change. The portable loop took a dozen instructions per
// row and 40 to pack the row flags: together more than the pair loop.
BGK_TARGET_AVX512 [[gnu::always_inline]] inline int beam_cells_8_avx512(const RowReach8& g, const LocalBeam& b,
                                                                         int32_t* cells) {
  alignas(64) int32_t first[kRows8], count[kRows8];
  alignas(64) uint8_t nonempty[kRows8];  // not needed here: the masks below say which rows have cells
  beam_row_intervals_8(g, b, first, count, nonempty);
  alignas(64) uint8_t row_cells[kRows8];  // bit x: cell x of the row is in its interval
  const __m512i one = _mm512_set1_epi32(1);
  for (int i = 0; i < kRows8; i += 16) {
    const __m512i n = _mm512_load_si512(count + i), x0 = _mm512_load_si512(first + i);
    // (The maskz forms: GCC 12 warns about the plain ones' undefined pass-through operand.)
    const __m512i bits =
        _mm512_maskz_sllv_epi32(0xFFFF, _mm512_sub_epi32(_mm512_maskz_sllv_epi32(0xFFFF, one, n), one), x0);
    _mm_store_si128(reinterpret_cast<__m128i*>(row_cells + i), _mm512_maskz_cvtepi32_epi8(0xFFFF, bits));
  }
  const __m512i pair_bits = _mm512_load_si512(row_cells);
  uint32_t pairs = _mm512_test_epi16_mask(pair_bits, pair_bits);  // bit p: rows 2p, 2p + 1 have cells
  const __m512i lane = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  int total = 0;
  for (; pairs != 0; pairs &= pairs - 1) {
    const int p = __builtin_ctz(pairs);
    uint16_t mask;
    std::memcpy(&mask, row_cells + 2 * p, sizeof mask);
    const __m512i index = _mm512_add_epi32(lane, _mm512_set1_epi32(16 * p));
    _mm512_storeu_si512(cells + total, _mm512_maskz_compress_epi32(mask, index));
    total += __builtin_popcount(mask);
  }
  _mm512_storeu_si512(cells + total, _mm512_set1_epi32(kCells8));
  return total;
}
#endif

// beam_row_mask_8 for `count` beams.
void beam_row_masks_8(const RowReach8& g, const LocalBeam* beams, size_t count, uint64_t* masks);

}  // namespace bgkmap
