#include "bgkmap/integrate/cpu_integrator.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

#include "bgkmap/core/bgk_math.h"

// Function multiversioning: one binary, the widest vectors the CPU has. Each clone evaluates the
// same float expressions (no FMA contraction under -std=c++17), so maps do not depend on it.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define BGK_CPU_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#define BGK_INLINE_INTO_CLONES [[gnu::always_inline]] inline
#else
#define BGK_CPU_CLONES
#define BGK_INLINE_INTO_CLONES inline
#endif

namespace bgkmap {

CpuIntegrator::CpuIntegrator(int threads) : threads_(threads > 0 ? threads : omp_get_max_threads()) {}

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

// Narrows [s0, s1] to the parameters s where q + s u lies within [c - r, c + r].
BGK_INLINE_INTO_CLONES bool clip_to_slab(float q, float u, float c, float r, float& s0, float& s1) {
  if (u == 0.0f) return std::fabs(q - c) <= r;
  float ta = (c - r - q) / u, tb = (c + r - q) / u;
  if (ta > tb) std::swap(ta, tb);
  s0 = std::max(s0, ta);
  s1 = std::min(s1, tb);
  return s0 <= s1;
}

struct BlockGeometry {
  int n;
  float res, inv_res, ell, ell2, inv_ell2, sigma0;
  // Culling distance: ell padded so that float rounding in the culling tests never drops a
  // cell the kernel would reach (the kernel itself decides exactly).
  float reach, reach2;
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

// Any block size: alpha[cell] += k(|cell - p|) for the cells within ell of one hit. Rows of cells are culled by
// their y/z distance; each remaining row is one vectorized loop over x.
BGK_INLINE_INTO_CLONES void add_hit(const BlockGeometry& g, const LocalHit& p, float* alpha, uint64_t& evaluated, uint64_t& within) {
  int x0, x1, y0, y1, z0, z1;
  if (!cell_span(p.x - g.ell, p.x + g.ell, g.inv_res, g.n, x0, x1) ||
      !cell_span(p.y - g.ell, p.y + g.ell, g.inv_res, g.n, y0, y1) ||
      !cell_span(p.z - g.ell, p.z + g.ell, g.inv_res, g.n, z0, z1))
    return;
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
  for (int z = z0; z <= z1; ++z) {
    float zs0 = b.s_min, zs1 = b.s_max;
    if (!clip_to_slab(b.qz, b.uz, z * g.res, reach, zs0, zs1)) continue;
    const float ya = b.qy + zs0 * b.uy, yb = b.qy + zs1 * b.uy;
    int y0, y1;
    if (!cell_span(std::min(ya, yb) - reach, std::max(ya, yb) + reach, g.inv_res, g.n, y0, y1)) continue;
    for (int y = y0; y <= y1; ++y) {
      float s0 = zs0, s1 = zs1;
      if (!clip_to_slab(b.qy, b.uy, y * g.res, reach, s0, s1)) continue;
      const float xa = b.qx + s0 * b.ux, xb = b.qx + s1 * b.ux;
      int x0, x1;
      if (!cell_span(std::min(xa, xb) - reach, std::max(xa, xb) + reach, g.inv_res, g.n, x0, x1)) continue;
      float* row = beta + (z * g.n + y) * g.n;
      within += beam_row<0>(g, row + x0, x0, y * g.res, z * g.res, b, x1 - x0 + 1);
      evaluated += static_cast<uint64_t>(x1 - x0 + 1);
    }
  }
}

// The common 8^3 block, in runs of 4 cells (run j: row j / 2, cells x = 4 (j % 2) .. + 3).
//
// Rows: the distance from a row's line (all x, fixed y and z) to a segment is the 2-D distance
// d_min in the y-z plane from (y, z) to the segment's projection, so a row with d_min beyond
// reach holds no cell within reach. Runs: a cell of the row within reach of the segment has its
// nearest segment point among those whose y-z distance to the row is within reach (parameters
// [t_lo, t_hi], a quadratic's roots), and lies within w = sqrt(reach^2 - d_min^2) of that point in
// x; so only cells in [min x(t), max x(t)] +- w can be reached. One vectorized pass over the 64
// rows per observation gives both tests (a hit is a zero-length segment); the kept runs are
// evaluated four per 16-lane loop. Which pairs are evaluated changes nothing but speed: every cell
// gets the same value, in the same order, as when every cell is evaluated (the kernel is zero
// beyond l, and reach pads l by 1e-4 l against the tests' rounding).
constexpr int kRows8 = 64;
constexpr int kRuns8 = 2 * kRows8;

// Indices of the runs that can hold a cell within reach of the segment a -> b (block frame, a
// and b within the block grown by reach); returns their count.
BGK_INLINE_INTO_CLONES int runs_near_8(const BlockGeometry& g, float ax, float ay, float az, float bx, float by,
                                       float bz, uint8_t* runs) {
  const float vx = bx - ax, vy = by - ay, vz = bz - az;
  const float vv = vy * vy + vz * vz;
  const float inv_vv = vv > 0.0f ? 1.0f / vv : 0.0f;
  const float pad = 1e-3f * g.res;  // x-extent slack against rounding in the roots
  alignas(64) uint8_t keep[kRuns8];
#pragma omp simd
  for (int i = 0; i < kRows8; ++i) {
    const float py = (i & 7) * g.res - ay, pz = (i >> 3) * g.res - az;
    const float pv = py * vy + pz * vz, pp = py * py + pz * pz;
    float t = pv * inv_vv;
    t = t < 0.0f ? 0.0f : (t > 1.0f ? 1.0f : t);
    const float dy = py - t * vy, dz = pz - t * vz;
    const float d2_min = dy * dy + dz * dz;
    const bool row = d2_min <= g.reach2;
    // Parameters whose y-z distance is within reach: vv t^2 - 2 pv t + pp - reach2 <= 0.
    const float disc = pv * pv - vv * (pp - g.reach2);
    const float root = BGK_SQRT(disc > 0.0f ? disc : 0.0f);
    float t_lo = vv > 0.0f ? (pv - root) * inv_vv : 0.0f, t_hi = vv > 0.0f ? (pv + root) * inv_vv : 1.0f;
    t_lo = t_lo < 0.0f ? 0.0f : (t_lo > t ? t : t_lo);  // keep the nearest point t inside
    t_hi = t_hi > 1.0f ? 1.0f : (t_hi < t ? t : t_hi);
    const float xa = ax + t_lo * vx, xb = ax + t_hi * vx;
    const float slack = g.reach2 - d2_min;
    const float w = BGK_SQRT(slack > 0.0f ? slack : 0.0f) + pad;
    const float x_lo = (xa < xb ? xa : xb) - w, x_hi = (xa < xb ? xb : xa) + w;
    keep[2 * i] = row && x_lo <= 3 * g.res && x_hi >= 0.0f;
    keep[2 * i + 1] = row && x_lo <= 7 * g.res && x_hi >= 4 * g.res;
  }
  // Compaction eight flags (bytes of 0 or 1) at a time: most words are zero.
  int count = 0;
  for (int i = 0; i < kRuns8; i += 8) {
    uint64_t word;
    std::memcpy(&word, keep + i, sizeof word);
    for (; word != 0; word &= word - 1) runs[count++] = static_cast<uint8_t>(i + (__builtin_ctzll(word) >> 3));
  }
  return count;
}

// Four runs' cells as the 16 lanes of one loop; a missing run gets cells far away (zero weight)
// that write to a sink.
struct RunLanes {
  float x[16], y[16], z[16];
  float* dst[4];
};

BGK_INLINE_INTO_CLONES void fill_lanes(const BlockGeometry& g, const uint8_t* runs, int count, float* cells,
                                       float* sink, RunLanes& lanes) {
  for (int u = 0; u < 4; ++u) {
    const bool real = u < count;
    const int run = real ? runs[u] : 0;
    const int row = run >> 1, x0 = 4 * (run & 1);
    const float y = real ? (row & 7) * g.res : 1e6f, z = real ? (row >> 3) * g.res : 1e6f;
    for (int j = 0; j < 4; ++j) {
      lanes.x[4 * u + j] = (x0 + j) * g.res;
      lanes.y[4 * u + j] = y;
      lanes.z[4 * u + j] = z;
    }
    lanes.dst[u] = real ? cells + row * 8 + x0 : sink;
  }
}

BGK_INLINE_INTO_CLONES void scatter_lanes(const RunLanes& lanes, const float* k) {
  for (int u = 0; u < 4; ++u)
    for (int j = 0; j < 4; ++j) lanes.dst[u][j] += k[4 * u + j];
}

BGK_INLINE_INTO_CLONES void add_hit_8(const BlockGeometry& g, const LocalHit& p, float* alpha, uint64_t& evaluated,
                                      uint64_t& within) {
  if (p.x < -g.reach || p.x > 7 * g.res + g.reach) return;
  uint8_t runs[kRuns8];
  const int count = runs_near_8(g, p.x, p.y, p.z, p.x, p.y, p.z, runs);
  float sink[4];
  RunLanes lanes;
  for (int first = 0; first < count; first += 4) {
    fill_lanes(g, runs + first, count - first, alpha, sink, lanes);
    float k[16];
    uint32_t near = 0;
#pragma omp simd reduction(+ : near)
    for (int i = 0; i < 16; ++i) {
      const float dx = lanes.x[i] - p.x, dy = lanes.y[i] - p.y, dz = lanes.z[i] - p.z;
      const float d2 = dx * dx + (dy * dy + dz * dz);
      k[i] = bgk_sparse_kernel_d2(d2, g.inv_ell2, g.sigma0);
      near += d2 < g.ell2;
    }
    scatter_lanes(lanes, k);
    within += near;
  }
  evaluated += 4 * static_cast<uint64_t>(count);
}

BGK_INLINE_INTO_CLONES void add_beam_8(const BlockGeometry& g, const LocalBeam& b, float* beta, uint64_t& evaluated,
                                       uint64_t& within) {
  // The part of the segment inside the block's cells grown by reach (the rest cannot matter),
  // so the tests work on small coordinates whatever the beam's length.
  float s0 = b.s_min, s1 = b.s_max;
  const float lo = -g.reach, hi = 7 * g.res + g.reach, mid = 0.5f * (lo + hi), half = 0.5f * (hi - lo);
  if (!clip_to_slab(b.qx, b.ux, mid, half, s0, s1) || !clip_to_slab(b.qy, b.uy, mid, half, s0, s1) ||
      !clip_to_slab(b.qz, b.uz, mid, half, s0, s1))
    return;
  uint8_t runs[kRuns8];
  const int count = runs_near_8(g, b.qx + s0 * b.ux, b.qy + s0 * b.uy, b.qz + s0 * b.uz, b.qx + s1 * b.ux,
                                b.qy + s1 * b.uy, b.qz + s1 * b.uz, runs);
  float sink[4];
  RunLanes lanes;
  for (int first = 0; first < count; first += 4) {
    fill_lanes(g, runs + first, count - first, beta, sink, lanes);
    float k[16];
    uint32_t near = 0;
#pragma omp simd reduction(+ : near)
    for (int i = 0; i < 16; ++i) {
      const float d2 = bgk_anchored_segment_dist2(lanes.x[i], lanes.y[i], lanes.z[i], b.qx, b.qy, b.qz, b.ux, b.uy,
                                                  b.uz, b.s_min, b.s_max);
      k[i] = bgk_sparse_kernel_d2(d2, g.inv_ell2, g.sigma0);
      near += d2 < g.ell2;
    }
    scatter_lanes(lanes, k);
    within += near;
  }
  evaluated += 4 * static_cast<uint64_t>(count);
}

// Sparse kernel: every hit and beam of the block against the cells it can reach. Compiled for
// AVX-512, AVX2 and baseline x86-64, chosen at load time for the machine it runs on.
BGK_CPU_CLONES void integrate_block_sparse(const BlockWork& work, const ScanBuckets& buckets,
                                           const BlockGeometry& g, BlockScratch& scratch, Cell* cells,
                                           IntegrateStats& stats) {
  const size_t count = static_cast<size_t>(g.n) * g.n * g.n;
  scratch.alpha.assign(count, 0.0f);
  scratch.beta.assign(count, 0.0f);
  uint64_t evaluated = 0, within = 0;
  const LocalHit* hits = buckets.hits.data() + work.hit_begin;
  const LocalBeam* beams = buckets.beams.data() + work.beam_begin;
  if (g.n == 8) {
    for (uint32_t h = 0; h < work.hit_count; ++h) add_hit_8(g, hits[h], scratch.alpha.data(), evaluated, within);
    for (uint32_t b = 0; b < work.beam_count; ++b) add_beam_8(g, beams[b], scratch.beta.data(), evaluated, within);
  } else {
    for (uint32_t h = 0; h < work.hit_count; ++h) add_hit(g, hits[h], scratch.alpha.data(), evaluated, within);
    for (uint32_t b = 0; b < work.beam_count; ++b) add_beam(g, beams[b], scratch.beta.data(), evaluated, within);
  }
  for (size_t i = 0; i < count; ++i) {
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
  stats.pairs_evaluated += static_cast<uint64_t>(local) * (work.hit_count + work.beam_count);
  stats.pairs_within_support += within;
}

}  // namespace

void CpuIntegrator::integrate(const ScanObservations& obs, const ScanBuckets& buckets, BgkMap& map,
                              IntegrateStats& stats) {
  (void)obs;  // the buckets carry every observation in its block's frame
  const Grid& grid = map.grid();
  const KernelParams& kernel = map.params().kernel;
  BlockGeometry g;
  g.n = grid.cells_per_side();
  g.res = static_cast<float>(grid.resolution());
  g.inv_res = static_cast<float>(1.0 / grid.resolution());
  g.ell = kernel.ell_m;
  g.ell2 = kernel.ell_m * kernel.ell_m;
  g.inv_ell2 = kernel.inverse_ell_squared();
  g.sigma0 = kernel.sigma0;
  g.reach = kernel.ell_m * (1.0f + 1e-4f);
  g.reach2 = g.reach * g.reach;
  const int64_t count = static_cast<int64_t>(buckets.blocks.size());
  uint64_t evaluated = 0, within = 0;
#pragma omp parallel num_threads(threads_) reduction(+ : evaluated, within)
  {
    IntegrateStats local;
    BlockScratch scratch;
#pragma omp for schedule(dynamic, 4)
    for (int64_t i = 0; i < count; ++i) {
      const BlockWork& work = buckets.blocks[static_cast<size_t>(i)];
      Cell* cells = map.block_cells(work.slot);
      if (kernel.type == KernelType::kBox)
        integrate_block_box(work, buckets, g, cells, local);
      else
        integrate_block_sparse(work, buckets, g, scratch, cells, local);
    }
    evaluated += local.pairs_evaluated;
    within += local.pairs_within_support;
  }
  stats.pairs_evaluated += evaluated;
  stats.pairs_within_support += within;
}

}  // namespace bgkmap
