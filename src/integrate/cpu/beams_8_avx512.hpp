// The CPU back end's loop for the beams of 8^3 blocks in AVX-512 intrinsics, shared with the
// pair-evaluation roofline benchmark (bench/roofline_kernel.cpp). Private to the library.
#pragma once

#include "integrate/cpu/cpu_clones.hpp"

#if BGK_AVX512_BEAMS
#include <algorithm>
#include <cstdint>
#include <limits>

#include "core/bgk_math.h"
#include "bgkmap/integrate/bucketing.hpp"
#include "integrate/beam_rows_8.hpp"

namespace bgkmap {

// The 8^3 beams in AVX-512 intrinsics. The portable pair loop (cpu_integrator.cpp's
// add_beam_rows_8) ran at about half the rate its instructions allow: each row pair was one chain
// of dependent steps (distance, square root, polynomial, add) some hundred cycles long, and a
// beam's few row pairs ended in a mispredicted branch. Here the (beam, row pair) items of up to 64 beams are listed first and
// evaluated in one loop without branches, software pipelined in four stages, so that each
// stage's operands were computed in an earlier iteration. The floats are those of
// bgk_offset_segment_dist2 and bgk_sparse_kernel_d2, operation by operation (a test compares the
// sums with the portable loop's), added to each cell in bucket order: the sums do not change.

// Cell offsets of an 8^3 block for row pair p (rows 2p and 2p + 1; lane i at x = i & 7,
// y = 2 (p & 3) + (i >> 3), z = p >> 2), times the resolution.
struct alignas(64) RowPairCells {
  float y[16], z[16];
};

// The items of a batch of beams: a beam's byte offset in the batch and the row pair's index times 64
// (the row pair's cells lie 64 bytes apart, its RowPairCells 128), two loads per item.
constexpr uint32_t kBeamBatch = 64;
struct BeamItems {
  alignas(64) uint32_t beam_bytes[kBeamBatch * 32 + 16];
  alignas(64) uint32_t pair_bytes[kBeamBatch * 32 + 16];
};

// Lists the row pairs with row bits of beams[0 .. count) (count <= kBeamBatch); returns how many.
BGK_TARGET_AVX512 [[gnu::always_inline]] inline uint32_t list_beam_items(const RowReach8& rows_reach,
                                                                     const LocalBeam* beams, uint32_t count,
                                                                     BeamItems& items) {
  const __m512i lane = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  const __m512i pairs_lo = _mm512_slli_epi32(lane, 6);  // row pairs 0-15 and 16-31, times 64
  const __m512i pairs_hi = _mm512_add_epi32(pairs_lo, _mm512_set1_epi32(16 * 64));
  uint32_t n = 0;
  for (uint32_t k = 0; k < count; ++k) {
    const uint64_t rows = beam_row_mask_8_avx512(rows_reach, beams[k]);
    // Bit p: row 2p or 2p + 1 reached.
    const uint32_t pairs = static_cast<uint32_t>(_pext_u64(rows | rows >> 1, 0x5555555555555555ull));
    const __m512i beam = _mm512_set1_epi32(static_cast<int>(k * sizeof(LocalBeam)));
    for (int half = 0; half < 2; ++half) {
      const __mmask16 mask = static_cast<__mmask16>(pairs >> (16 * half));
      _mm512_storeu_si512(items.beam_bytes + n, beam);
      _mm512_storeu_si512(items.pair_bytes + n, _mm512_maskz_compress_epi32(mask, half ? pairs_hi : pairs_lo));
      n += static_cast<uint32_t>(__builtin_popcount(mask));
    }
  }
  return n;
}

// bgk_offset_segment_dist2 for the 16 cells of a row pair, whose x, y and z offsets from the
// block's first cell are x, yz.y, yz.z.
BGK_TARGET_AVX512 [[gnu::always_inline]] inline __m512 row_pair_dist2_avx512(__m512 x, const RowPairCells& yz,
                                                                         const LocalBeam& b) {
  const __mmask16 kAll = 0xFFFF;  // the maskz forms: GCC 12 warns about the plain ones' pass-through
  const __m512 ux = _mm512_set1_ps(b.ux), uy = _mm512_set1_ps(b.uy), uz = _mm512_set1_ps(b.uz);
  const __m512 wx = _mm512_sub_ps(x, _mm512_set1_ps(b.qx));
  const __m512 wy = _mm512_sub_ps(_mm512_load_ps(yz.y), _mm512_set1_ps(b.qy));
  const __m512 wz = _mm512_sub_ps(_mm512_load_ps(yz.z), _mm512_set1_ps(b.qz));
  __m512 s = _mm512_fmadd_ps(wx, ux, _mm512_fmadd_ps(wy, uy, _mm512_mul_ps(wz, uz)));
  s = _mm512_maskz_max_ps(kAll, _mm512_set1_ps(b.s_min), s);  // s < s_min ? s_min : s
  s = _mm512_maskz_min_ps(kAll, _mm512_set1_ps(b.s_max), s);  // s > s_max ? s_max : s
  const __m512 dx = _mm512_fnmadd_ps(s, ux, wx), dy = _mm512_fnmadd_ps(s, uy, wy), dz = _mm512_fnmadd_ps(s, uz, wz);
  return _mm512_fmadd_ps(dx, dx, _mm512_fmadd_ps(dy, dy, _mm512_mul_ps(dz, dz)));
}

// What the loop needs of an 8^3 block's geometry and kernel.
struct Beams8Params {
  RowReach8 rows;
  float res, ell2, inv_ell2, sigma0;
};

// Adds the kernel values of beams[0 .. beam_count) (in the block's frame) to beta, the block's 512
// cells (x fastest), evaluating the row pairs their row bits flag; adds the pairs within ell to
// near_lanes (per lane) and returns the pairs evaluated.
BGK_TARGET_AVX512 inline uint64_t add_beams_8_avx512(const Beams8Params& g, const LocalBeam* beams, uint32_t beam_count,
                                                     float* beta, uint32_t near_lanes[16]) {
  uint64_t evaluated = 0;
  const __mmask16 kAll = 0xFFFF;
  const __m512i lane = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  const __m512 res = _mm512_set1_ps(g.res);
  const __m512 cell_x =
      _mm512_mul_ps(_mm512_maskz_cvtepi32_ps(kAll, _mm512_and_si512(lane, _mm512_set1_epi32(7))), res);
  RowPairCells pair_cells[32];
  for (int p = 0; p < 32; ++p) {
    const __m512i y = _mm512_add_epi32(_mm512_srli_epi32(lane, 3), _mm512_set1_epi32(2 * (p & 3)));
    _mm512_store_ps(pair_cells[p].y, _mm512_mul_ps(_mm512_maskz_cvtepi32_ps(kAll, y), res));
    _mm512_store_ps(pair_cells[p].z, _mm512_set1_ps(static_cast<float>(p >> 2) * g.res));
  }
  const __m512 inv_ell2 = _mm512_set1_ps(g.inv_ell2), sigma0 = _mm512_set1_ps(g.sigma0), ell2 = _mm512_set1_ps(g.ell2);
  const __m512 one = _mm512_set1_ps(1.0f), zero = _mm512_setzero_ps();
  const __m512 far = _mm512_set1_ps(std::numeric_limits<float>::infinity());
  __m512i counts = _mm512_loadu_si512(near_lanes);
  BeamItems items;
  alignas(64) float sink[16];
  for (uint32_t first = 0; first < beam_count; first += kBeamBatch) {
    const char* batch = reinterpret_cast<const char*>(beams + first);
    const uint32_t n = list_beam_items(g.rows, beams + first, std::min(kBeamBatch, beam_count - first), items);
    evaluated += 16 * static_cast<uint64_t>(n);
    // Stage 1: distances of item i; 2: square roots of item i - 1; 3: the polynomial of item i - 2;
    // 4: its product, added to the cells, of item i - 3. The stages start on distance +inf (kernel
    // 0, not within l) added to a sink, and the loop runs three items past the end (beam 0, row
    // pair 0: computed, never added).
    for (int extra = 0; extra < 3; ++extra) items.beam_bytes[n + extra] = items.pair_bytes[n + extra] = 0;
    __m512 d2_1 = far, d2_2 = far, r_2 = far, d2_3 = far, poly_3 = zero, u5_3 = zero;
    float *cells_1 = sink, *cells_2 = sink, *cells_3 = sink;
    for (uint32_t i = 0; i < n + 3; ++i) {
      const uint32_t pair_bytes = items.pair_bytes[i];
      const LocalBeam& b = *reinterpret_cast<const LocalBeam*>(batch + items.beam_bytes[i]);
      const RowPairCells& yz =
          *reinterpret_cast<const RowPairCells*>(reinterpret_cast<const char*>(pair_cells) + 2 * pair_bytes);
      const __m512 d2 = row_pair_dist2_avx512(cell_x, yz, b);
      float* cells = reinterpret_cast<float*>(reinterpret_cast<char*>(beta) + pair_bytes);

      const __m512 r_1 = _mm512_maskz_sqrt_ps(kAll, _mm512_mul_ps(d2_1, inv_ell2));

      // bgk_sparse_kernel_of_ratio; beyond l (r >= 1) u = 0 makes the kernel exactly +0 (the
      // polynomial is positive at t = -1), as its r < 1 test does.
      const __m512 u = _mm512_maskz_max_ps(kAll, _mm512_sub_ps(one, r_2), zero);
      const __m512 v = _mm512_mul_ps(u, u);
      const __m512 t = _mm512_fmadd_ps(_mm512_set1_ps(2.0f), v, _mm512_set1_ps(-1.0f));
      const __m512 t2 = _mm512_mul_ps(t, t);
      const __m512 t4 = _mm512_mul_ps(t2, t2);
      const __m512 p01 = _mm512_fmadd_ps(t, _mm512_set1_ps(BGK_SPARSE_P1), _mm512_set1_ps(BGK_SPARSE_P0));
      const __m512 p23 = _mm512_fmadd_ps(t, _mm512_set1_ps(BGK_SPARSE_P3), _mm512_set1_ps(BGK_SPARSE_P2));
      const __m512 p45 = _mm512_fmadd_ps(t, _mm512_set1_ps(BGK_SPARSE_P5), _mm512_set1_ps(BGK_SPARSE_P4));
      const __m512 p67 = _mm512_fmadd_ps(t, _mm512_set1_ps(BGK_SPARSE_P7), _mm512_set1_ps(BGK_SPARSE_P6));
      const __m512 poly = _mm512_fmadd_ps(t4, _mm512_fmadd_ps(t2, p67, p45), _mm512_fmadd_ps(t2, p23, p01));
      const __m512 u5 = _mm512_mul_ps(_mm512_mul_ps(v, v), u);

      const __m512 k = _mm512_mul_ps(sigma0, _mm512_mul_ps(u5_3, poly_3));
      _mm512_storeu_ps(cells_3, _mm512_add_ps(_mm512_loadu_ps(cells_3), k));
      counts = _mm512_mask_sub_epi32(counts, _mm512_cmp_ps_mask(d2_3, ell2, _CMP_LT_OQ), counts, _mm512_set1_epi32(-1));

      d2_3 = d2_2, poly_3 = poly, u5_3 = u5, cells_3 = cells_2;
      d2_2 = d2_1, r_2 = r_1, cells_2 = cells_1;
      d2_1 = d2, cells_1 = cells;
    }
  }
  _mm512_storeu_si512(near_lanes, counts);
  return evaluated;
}

}  // namespace bgkmap
#endif
