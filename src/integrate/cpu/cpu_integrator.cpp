#include "bgkmap/integrate/cpu_integrator.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

#include "core/bgk_math.h"
#include "core/parallel_errors.hpp"
#include "integrate/beam_rows_8.hpp"
#include "integrate/cpu/beams_8_avx512.hpp"
#include "integrate/cpu/cpu_clones.hpp"

namespace bgkmap {

CpuIntegrator::CpuIntegrator(int threads, bool avx512_beams)
    : threads_(threads > 0 ? threads : omp_get_max_threads()), avx512_beams_(avx512_beams) {}

BackendInfo CpuIntegrator::info() const {
  BackendInfo b;
  b.name = "cpu";
  b.device = "host CPU (OpenMP)";
  b.threads = threads_;
  return b;
}

namespace {

// Per-thread accumulators for one block (structure of arrays, so rows of cells vectorize).
struct BlockScratch {
  std::vector<float> alpha, beta;
};

// The cells [first, last] of one axis (cell i at i * res) whose coordinate lies in [lo, hi],
// padded by a hair so that float rounding never drops a cell; the kernel decides exactly.
BGK_INLINE_INTO_CLONES bool cell_span(float lo, float hi, float inv_res, int n, int& first, int& last) {
  const float pad = 1e-4f;
  const float a = std::max(lo * inv_res - pad, -1.0f), b = std::min(hi * inv_res + pad, static_cast<float>(n));
  first = std::max(0, static_cast<int>(std::ceil(a)));
  last = std::min(n - 1, static_cast<int>(std::floor(b)));
  return first <= last;
}

struct BlockGeometry {
  int n;
  float res, inv_res, ell, ell2, inv_ell2, sigma0;
  // Culling distance: ell padded so that float rounding in the culling tests never drops a
  // cell the kernel would reach (the kernel itself decides exactly).
  float reach, reach2;
  // The 8^3 beam path's row intervals (beam_rows_8.hpp).
  RowReach8 rows;
  // A planar map's layer: the cells' z inside the block (-1: every layer; in 8^3 blocks also
  // rows.layer_rows); the other layers' cells are left as they are.
  int layer = -1;
};

// One row of cells x = first .. first + count - 1 (count = N when N > 0, a compile-time length
// that vectorizes without remainder loops) against one hit; returns how many were within ell.
template <int N>
BGK_INLINE_INTO_CLONES uint32_t hit_row(const BlockGeometry& g, float* row, int first, float px, float dyz2, int count = N) {
  const int len = N > 0 ? N : count;
  uint32_t near = 0;  // 32-bit: the same lane width as the floats
#pragma omp simd reduction(+ : near)
  for (int i = 0; i < len; ++i) {
    const float dx = (first + i) * g.res - px;
    const float d2 = dx * dx + dyz2;
    row[i] += bgk_sparse_kernel_d2(d2, g.inv_ell2, g.sigma0);
    near += d2 < g.ell2;
  }
  return near;
}

// The same for one beam's free segment.
template <int N>
BGK_INLINE_INTO_CLONES uint32_t beam_row(const BlockGeometry& g, float* row, int first, float cy, float cz,
                                         const LocalBeam& b, int count = N) {
  const int len = N > 0 ? N : count;
  uint32_t near = 0;
#pragma omp simd reduction(+ : near)
  for (int i = 0; i < len; ++i) {
    const float d2 = bgk_anchored_segment_dist2((first + i) * g.res, cy, cz, b.qx, b.qy, b.qz, b.ux, b.uy, b.uz,
                                                b.s_min, b.s_max);
    row[i] += bgk_sparse_kernel_d2(d2, g.inv_ell2, g.sigma0);
    near += d2 < g.ell2;
  }
  return near;
}

// Two rows of an 8^3 block against one hit in one 16-lane loop (AVX-512 fills all its lanes;
// narrower vectors take two steps). Lanes 0-7 are row `a`, 8-15 row `b`. Each cell gets the same
// value, in the same order, as from two single-row calls.
struct PendingRow {
  float* row = nullptr;
  float dyz2 = 0;  // squared y/z distance of the row from the hit
};

// Pairs within ell, counted per lane and summed once per block: a horizontal sum per row pair
// cost as much as a fifth of the pair loop.
struct alignas(64) LaneCounts {
  uint32_t lane[16] = {};
  uint64_t total() const {
    uint64_t sum = 0;
    for (uint32_t n : lane) sum += n;
    return sum;
  }
};

// Adds lanes 0-7 of k to row a and lanes 8-15 to row b. The rows are distinct: simd says they do
// not overlap, so each is one 8-wide add (the compiler, unsure, made 16 scalar ones).
BGK_INLINE_INTO_CLONES void add_row_pair(const PendingRow& a, const PendingRow& b, const float* k) {
#pragma omp simd
  for (int i = 0; i < 8; ++i) {
    a.row[i] += k[i];
    b.row[i] += k[8 + i];
  }
}

BGK_INLINE_INTO_CLONES void hit_rows_8x2(const BlockGeometry& g, const PendingRow& a, const PendingRow& b, float px,
                                         LaneCounts& near) {
  float k[16];
#pragma omp simd
  for (int i = 0; i < 16; ++i) {
    const float dx = (i & 7) * g.res - px;
    const float d2 = dx * dx + (i < 8 ? a.dyz2 : b.dyz2);
    k[i] = bgk_sparse_kernel_d2(d2, g.inv_ell2, g.sigma0);
    near.lane[i] += d2 < g.ell2;
  }
  add_row_pair(a, b, k);
}

// Any block size: alpha[cell] += k(|cell - p|) for the cells within ell of one hit. Rows of cells are culled by
// their y/z distance; each remaining row is one vectorized loop over x.
// A planar map's cells: the z range [z0, z1] cut to its layer (empty when it is not there).
BGK_INLINE_INTO_CLONES void keep_layer(const BlockGeometry& g, int& z0, int& z1) {
  if (g.layer < 0) return;
  z0 = std::max(z0, g.layer);
  z1 = std::min(z1, g.layer);
}

BGK_INLINE_INTO_CLONES void add_hit(const BlockGeometry& g, const LocalHit& p, float* alpha, uint64_t& evaluated, uint64_t& within) {
  int x0, x1, y0, y1, z0, z1;
  if (!cell_span(p.x - g.ell, p.x + g.ell, g.inv_res, g.n, x0, x1) ||
      !cell_span(p.y - g.ell, p.y + g.ell, g.inv_res, g.n, y0, y1) ||
      !cell_span(p.z - g.ell, p.z + g.ell, g.inv_res, g.n, z0, z1))
    return;
  keep_layer(g, z0, z1);
  for (int z = z0; z <= z1; ++z) {
    const float dz = z * g.res - p.z;
    for (int y = y0; y <= y1; ++y) {
      const float dy = y * g.res - p.y;
      const float dyz2 = dy * dy + dz * dz;
      if (dyz2 >= g.ell2) continue;
      float* row = alpha + (z * g.n + y) * g.n;
      within += hit_row<0>(g, row + x0, x0, p.x, dyz2, x1 - x0 + 1);
      evaluated += static_cast<uint64_t>(x1 - x0 + 1);
    }
  }
}

// Any block size: beta[cell] += k(distance from cell to the free segment) for the cells within ell of it: per
// z-slab and then per row, the segment is clipped to the cells' neighbourhood, and only the x
// range it can reach is evaluated.
BGK_INLINE_INTO_CLONES void add_beam(const BlockGeometry& g, const LocalBeam& b, float* beta, uint64_t& evaluated, uint64_t& within) {
  const float az = b.qz + b.s_min * b.uz, ez = b.qz + b.s_max * b.uz;
  const float reach = g.ell * (1.0f + 1e-5f);
  int z0, z1;
  if (!cell_span(std::min(az, ez) - reach, std::max(az, ez) + reach, g.inv_res, g.n, z0, z1)) return;
  keep_layer(g, z0, z1);
  for (int z = z0; z <= z1; ++z) {
    float zs0 = b.s_min, zs1 = b.s_max;
    const float zc = z * g.res;
    if (!bgk_clip_to_slab(b.qz, b.uz, zc - reach, zc + reach, &zs0, &zs1)) continue;
    const float ya = b.qy + zs0 * b.uy, yb = b.qy + zs1 * b.uy;
    int y0, y1;
    if (!cell_span(std::min(ya, yb) - reach, std::max(ya, yb) + reach, g.inv_res, g.n, y0, y1)) continue;
    for (int y = y0; y <= y1; ++y) {
      float s0 = zs0, s1 = zs1;
      const float yc = y * g.res;
      if (!bgk_clip_to_slab(b.qy, b.uy, yc - reach, yc + reach, &s0, &s1)) continue;
      const float xa = b.qx + s0 * b.ux, xb = b.qx + s1 * b.ux;
      int x0, x1;
      if (!cell_span(std::min(xa, xb) - reach, std::max(xa, xb) + reach, g.inv_res, g.n, x0, x1)) continue;
      float* row = beta + (z * g.n + y) * g.n;
      within += beam_row<0>(g, row + x0, x0, y * g.res, z * g.res, b, x1 - x0 + 1);
      evaluated += static_cast<uint64_t>(x1 - x0 + 1);
    }
  }
}

// Hits in the common 8^3 block. The distance from a row's line (all x, fixed y and z) to a
// point is the 2-D distance in the y-z plane, so one vectorized pass over the 64 rows finds every
// row that can hold a cell within reach. The kept rows are then evaluated whole, two per 16-lane
// loop. Which pairs are evaluated changes nothing but speed: every cell gets the same value, in
// the same order, as when every row is evaluated.

// Indices of the rows within `reach2` of the y-z point (py, pz); returns their count.
BGK_INLINE_INTO_CLONES int rows_near_8(const BlockGeometry& g, float py, float pz, uint8_t* rows) {
  alignas(64) uint8_t keep[kRows8];
#pragma omp simd
  for (int i = 0; i < kRows8; ++i) {
    const float dy = (i & 7) * g.res - py, dz = (i >> 3) * g.res - pz;
    keep[i] = (dy * dy + dz * dz <= g.reach2) & static_cast<uint8_t>((g.rows.layer_rows >> i) & 1);
  }
  // Compaction eight flags (bytes of 0 or 1) at a time: most words are zero.
  int count = 0;
  for (int i = 0; i < kRows8; i += 8) {
    uint64_t word;
    std::memcpy(&word, keep + i, sizeof word);
    for (; word != 0; word &= word - 1) rows[count++] = static_cast<uint8_t>(i + (__builtin_ctzll(word) >> 3));
  }
  return count;
}

BGK_INLINE_INTO_CLONES void add_hit_8(const BlockGeometry& g, const LocalHit& hit, float* alpha, uint64_t& evaluated,
                                      uint64_t& within, LaneCounts& near) {
  const LocalHit p = hit;  // a copy, as in add_beam_rows_8
  if (p.x < -g.reach || p.x > 7 * g.res + g.reach) return;
  uint8_t rows[kRows8];
  const int count = rows_near_8(g, p.y, p.z, rows);
  auto pending = [&](int k) {
    const int y = rows[k] & 7, z = rows[k] >> 3;
    const float dy = y * g.res - p.y, dz = z * g.res - p.z;
    return PendingRow{alpha + rows[k] * 8, dy * dy + dz * dz};
  };
  int k = 0;
  for (; k + 1 < count; k += 2) hit_rows_8x2(g, pending(k), pending(k + 1), p.x, near);
  if (k < count) {
    const PendingRow last = pending(k);
    within += hit_row<8>(g, last.row, 0, p.x, last.dyz2);
  }
  evaluated += 8 * static_cast<uint64_t>(count);
}

// Beams in an 8^3 block, as the hits: the rows a beam can reach (beam_rows_8.hpp: one bit per
// row, from where the row's line comes within reach of the beam's line, within the segment's
// x-extent grown by reach) are evaluated whole, by row pairs: rows 2p and 2p + 1 are 16
// consecutive cells, one 16-lane loop with contiguous loads and stores, cheaper than gathering
// each row's exact interval of cells by index (docs/ALGORITHM.md, "The CPU back end"). Each cell
// still gets each beam of the block once, in bucket order, with the same float expression, and
// cells beyond reach get exactly 0: the sums do not change.
BGK_INLINE_INTO_CLONES void add_beam_rows_8(const BlockGeometry& g, const LocalBeam& beam, uint64_t rows, float* beta,
                                            uint64_t& evaluated, LaneCounts& near) {
  // A copy: the stores below could write through `beta` to the bucket's beam, so the compiler
  // would reload it in every iteration (integrate_block_sparse copies the geometry for the same
  // reason).
  const LocalBeam b = beam;
  uint64_t pairs = (rows | rows >> 1) & 0x5555555555555555ull;  // bit 2p: row 2p or 2p + 1 reached
  evaluated += 16 * static_cast<uint64_t>(__builtin_popcountll(pairs));
  // The cells' offsets from the anchor, once per beam: y for the four row pairs of a layer (lanes
  // 0-7 y = 2j, lanes 8-15 y = 2j + 1) and z per layer.
  alignas(64) float offset_y[4][16], offset_z[8];
  for (int j = 0; j < 4; ++j) {
#pragma omp simd
    for (int i = 0; i < 16; ++i) offset_y[j][i] = (2 * j + (i >> 3)) * g.res - b.qy;
  }
#pragma omp simd
  for (int z = 0; z < 8; ++z) offset_z[z] = z * g.res - b.qz;
  for (; pairs != 0; pairs &= pairs - 1) {
    const int row = __builtin_ctzll(pairs);  // even: cells row * 8 .. row * 8 + 15
    const float* wy = offset_y[(row >> 1) & 3];
    const float wz = offset_z[row >> 3];
    float* cells = beta + row * 8;
#pragma omp simd
    for (int i = 0; i < 16; ++i) {
      const float d2 =
          bgk_offset_segment_dist2((i & 7) * g.res - b.qx, wy[i], wz, b.ux, b.uy, b.uz, b.s_min, b.s_max);
      cells[i] += bgk_sparse_kernel_d2(d2, g.inv_ell2, g.sigma0);
      near.lane[i] += d2 < g.ell2;
    }
  }
}

// Sparse kernel: every hit and beam of the block against the cells it can reach. Compiled for
// AVX-512, AVX2 and baseline x86-64, chosen at load time for the machine it runs on.
BGK_CPU_CLONES void integrate_block_sparse(const BlockWork& work, const ScanBuckets& buckets,
                                           const BlockGeometry& geometry, bool avx512_beams, BlockScratch& scratch,
                                           Cell* cells, IntegrateStats& stats) {
  // A local copy: stores through the scratch pointers cannot reach it, so the pair loops keep
  // its values in registers instead of reloading them after every scatter.
  const BlockGeometry g = geometry;
  const size_t count = static_cast<size_t>(g.n) * g.n * g.n;
  scratch.alpha.assign(count, 0.0f);
  scratch.beta.assign(count, 0.0f);
  uint64_t evaluated = 0, within = 0;
  const LocalHit* hits = buckets.hits.data() + work.hit_begin;
  const LocalBeam* beams = buckets.beams.data() + work.beam_begin;
  if (g.n == 8) {
    LaneCounts near;
    for (uint32_t h = 0; h < work.hit_count; ++h) add_hit_8(g, hits[h], scratch.alpha.data(), evaluated, within, near);
#if BGK_AVX512_BEAMS
    if (avx512_beams)
      evaluated += add_beams_8_avx512({g.rows, g.res, g.ell2, g.inv_ell2, g.sigma0}, beams, work.beam_count,
                                      scratch.beta.data(), near.lane);
    else
#endif
      for (uint32_t b = 0; b < work.beam_count; ++b)
        add_beam_rows_8(g, beams[b], beam_row_mask_8(g.rows, beams[b]), scratch.beta.data(), evaluated, near);
    within += near.total();
  } else {
    for (uint32_t h = 0; h < work.hit_count; ++h) add_hit(g, hits[h], scratch.alpha.data(), evaluated, within);
    for (uint32_t b = 0; b < work.beam_count; ++b) add_beam(g, beams[b], scratch.beta.data(), evaluated, within);
  }
  // A planar map adds its layer's cells only (in 8^3 blocks the others' sums are 0 already).
  const size_t layer_cells = static_cast<size_t>(g.n) * g.n;
  const size_t first = g.layer < 0 ? 0 : g.layer * layer_cells, end = g.layer < 0 ? count : first + layer_cells;
  for (size_t i = first; i < end; ++i) {
    cells[i].alpha += scratch.alpha[i];
    cells[i].beta += scratch.beta[i];
  }
  stats.pairs_evaluated += evaluated;
  stats.pairs_within_support += within;
}

// Box kernel (the counting sensor model): every cell against every observation. A check on the
// method, not a hot path.
void integrate_block_box(const BlockWork& work, const ScanBuckets& buckets, const BlockGeometry& g, Cell* cells,
                         IntegrateStats& stats) {
  const float half_size = 0.5f * g.res;
  const LocalHit* hits = buckets.hits.data() + work.hit_begin;
  const LocalBeam* beams = buckets.beams.data() + work.beam_begin;
  uint64_t within = 0;
  int local = 0;
  for (int lz = 0; lz < g.n; ++lz)
    for (int ly = 0; ly < g.n; ++ly)
      for (int lx = 0; lx < g.n; ++lx, ++local) {
        if (g.layer >= 0 && lz != g.layer) continue;  // not a planar map's layer
        const float cx = lx * g.res, cy = ly * g.res, cz = lz * g.res;
        float alpha = 0.0f, beta = 0.0f;
        for (uint32_t h = 0; h < work.hit_count; ++h)
          alpha += bgk_box_kernel_point(cx, cy, cz, half_size, hits[h].x, hits[h].y, hits[h].z);
        for (uint32_t k = 0; k < work.beam_count; ++k) {
          const LocalBeam& s = beams[k];
          beta += bgk_box_kernel_segment(cx, cy, cz, half_size, s.qx + s.s_min * s.ux, s.qy + s.s_min * s.uy,
                                         s.qz + s.s_min * s.uz, s.qx + s.s_max * s.ux, s.qy + s.s_max * s.uy,
                                         s.qz + s.s_max * s.uz);
        }
        within += static_cast<uint64_t>(alpha + beta);
        cells[local].alpha += alpha;
        cells[local].beta += beta;
      }
  const int evaluated_cells = g.layer < 0 ? local : g.n * g.n;
  stats.pairs_evaluated += static_cast<uint64_t>(evaluated_cells) * (work.hit_count + work.beam_count);
  stats.pairs_within_support += within;
}

}  // namespace

void CpuIntegrator::integrate(const ScanObservations& obs, const ScanBuckets& buckets, BgkMap& map,
                              IntegrateStats& stats) {
  // The buckets carry every observation in its block's frame; obs gives only their weight.
  const Grid& grid = map.grid();
  const KernelParams& kernel = map.params().kernel;
  BlockGeometry g;
  g.n = grid.cells_per_side();
  g.res = static_cast<float>(grid.resolution());
  g.inv_res = static_cast<float>(1.0 / grid.resolution());
  g.ell = kernel.ell_m;
  g.ell2 = kernel.ell_m * kernel.ell_m;
  g.inv_ell2 = kernel.inverse_ell_squared();
  g.sigma0 = kernel.sigma0 * obs.kernel_weight;
  g.reach = kernel.ell_m * (1.0f + 1e-4f);
  g.reach2 = g.reach * g.reach;
  g.rows = RowReach8::make(grid.resolution(), kernel.ell_m);
  if (map.params().preprocess.planar) {
    g.layer = map.layer_local_z();
    if (g.n == 8) g.rows.layer_rows = uint64_t{0xFF} << (8 * g.layer);
  }
  bool avx512_beams = avx512_beams_;  // asked for, and the CPU runs the AVX-512 loop
#if BGK_AVX512_BEAMS
  avx512_beams = avx512_beams && cpu_runs_avx512_beams();
#else
  avx512_beams = false;
#endif
  const int64_t count = static_cast<int64_t>(buckets.blocks.size());
  uint64_t evaluated = 0, within = 0;
  ParallelErrors errors;  // a block's scratch may fail to grow
#pragma omp parallel num_threads(threads_) reduction(+ : evaluated, within)
  {
    IntegrateStats local;
    BlockScratch scratch;
#pragma omp for schedule(dynamic, 4)
    for (int64_t i = 0; i < count; ++i)
      errors.run([&] {
        const BlockWork& work = buckets.blocks[static_cast<size_t>(i)];
        Cell* cells = map.block_cells(work.slot);
        if (kernel.type == KernelType::kBox)
          integrate_block_box(work, buckets, g, cells, local);
        else
          integrate_block_sparse(work, buckets, g, avx512_beams, scratch, cells, local);
      });
    evaluated += local.pairs_evaluated;
    within += local.pairs_within_support;
  }
  errors.rethrow();
  stats.pairs_evaluated += evaluated;
  stats.pairs_within_support += within;
}

}  // namespace bgkmap
