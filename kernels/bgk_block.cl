/* BGK-L block kernels (OpenCL C 1.2, no extensions): one work-group per block job, the job's
 * observations staged through local memory in tiles, and each work-item owning a run of up to
 * BGK_RUN consecutive cells along x (a whole row in blocks of fewer cells per side); on CPU
 * devices 8^3 blocks with the sparse kernel go to bgk_block_sparse_whole, one work-item per block
 * (bgk_block_sparse_pairs, two rows per work-item, can be chosen instead).
 *
 * A job is one block's hits and beams of one scan (a block with more observations than one
 * launch can hold is split into several jobs). Every cell sums its contributions in the order
 * the host gave them -- hits into alpha, then beams into beta -- with the same expressions as the
 * CPU back end (src/integrate/cpu/cpu_integrator.cpp: hit_row, beam_row), and adds the two sums
 * to the pool once. Each cell belongs to one work-item of one job per launch, so no atomics are
 * needed, and the launches of a scan run in order on an in-order queue.
 *
 * Per observation a work-item first tests whether it can reach its run at all
 * (bgk_*_reaches_run, or for beams in 8^3 blocks one bit per row from the host) and only then
 * evaluates the run's cells; that short fixed-length loop is what a CPU device (PoCL) vectorizes.
 * What the beam test needs (the beam clipped to the block grown by the reach, its x extent and y-z
 * projection) is computed once per beam and block while the tile is staged, not by every run.
 *
 * Geometry is block-local: cell (lx, ly, lz) sits at (lx, ly, lz) * resolution and the host gives
 * hits and beams relative to the block's first cell centre (core/bgk_layout.h: BgkLocalHit,
 * BgkLocalBeam; BgkJob). */

/* Implicit contraction into fma would round differently from the CPU path (the host builds with
 * -ffp-contract=off); OpenCL C allows it by default. The shared math's explicit BGK_FMA rounds
 * the same on both. */
#pragma OPENCL FP_CONTRACT OFF

#include "bgkmap/core/bgk_layout.h"
#include "core/bgk_math.h"

/* Observations staged per tile: a tile of beams is 8 KiB of local memory, and with the row bits,
 * the beams' reach and the reduction scratch the sparse kernel takes 19 KiB, within the 32 KiB
 * every OpenCL 1.2 device has. Fewer, larger tiles mean fewer barriers, each of which ends a loop
 * over the work-items on PoCL. */
#define BGK_TILE 256
/* Cells per work-item: a run along x (the host sizes work-groups by it: cells / min(n, BGK_RUN)). */
#define BGK_RUN 8

/* Copies `count` floats from global to local memory with the whole work-group. */
inline void bgk_stage(__local float* dst, __global const float* src, uint count) {
  for (uint i = get_local_id(0); i < count; i += get_local_size(0)) dst[i] = src[i];
}

/* Tile t0 of a job's `count` observations (records of `floats` floats from record `first` on):
 * once every work-item is done with the last tile, the work-group copies the next one, and where
 * `rows` is given their row bits, to local memory. Returns how many it holds (at most BGK_TILE). */
inline uint bgk_next_tile(__local float* tile, __global const float* records, uint first, uint t0, uint count,
                          uint floats, __global const ulong* rows, __local ulong* row_tile) {
  const uint m = min((uint)BGK_TILE, count - t0);
  barrier(CLK_LOCAL_MEM_FENCE);
  bgk_stage(tile, records + (size_t)(first + t0) * floats, m * floats);
  if (rows)
    for (uint i = get_local_id(0); i < m; i += get_local_size(0)) row_tile[i] = rows[first + t0 + i];
  barrier(CLK_LOCAL_MEM_FENCE);
  return m;
}

/* Sums the work-group's values of `mine`; every work-item gets the total. The work-group size
 * is a power of two (the host makes sure of it). */
inline ulong bgk_group_sum(ulong mine, __local ulong* scratch) {
  const uint lid = get_local_id(0);
  scratch[lid] = mine;
  for (uint stride = get_local_size(0) / 2; stride > 0; stride /= 2) {
    barrier(CLK_LOCAL_MEM_FENCE);
    if (lid < stride) scratch[lid] += scratch[lid + stride];
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  const ulong total = scratch[0];
  barrier(CLK_LOCAL_MEM_FENCE);
  return total;
}

/* Run tests. A run is skipped for an observation only when none of its cells would get a
 * non-zero kernel value, so the tests change which pairs are computed, never the sums. Every
 * pair (cell, point of the observation) is at least as far apart in x as the gap between their
 * x ranges, and in y-z as the row is from the observation's y-z projection, so the sum of the
 * two squares bounds every cell's d2 from below. It must clear the support by 0.1%, far more
 * than the float error of either computation (~1e-6 relative in block-local coordinates). For a
 * hit the bound is even exact: dyz2 is every cell's own y-z part, the gap is the nearest cell's
 * own dx, and float addition of non-negative terms is monotone. */
inline float bgk_gap(float lo, float hi, float a, float b) { /* between [lo, hi] and [a, b] */
  return a > hi ? a - hi : (b < lo ? lo - b : 0.0f);
}

inline bool bgk_hit_reaches_run(float x_lo, float x_hi, float dyz2, float px, float reach2) {
  const float gx = bgk_gap(x_lo, x_hi, px, px);
  return gx * gx + dyz2 < reach2;
}

/* What every run of a block tests a beam against, computed once per (block, beam) while staging:
 * the segment clipped to the block's cells grown by the reach (the rest cannot matter), as its
 * x extent and its y-z projection a + t v, t in [0, 1], with 1 / |v|^2. A beam that misses the
 * grown block gets an empty x extent (x_min > x_max), which no run reaches.
 * In 8^3 blocks (host_rows) the host gives instead, per beam, one bit per row: set when some
 * point of the row's cells' x-range, cut to the segment's x-extent grown by the reach, lies within
 * the reach of the beam's line (src/integrate/beam_rows_8.hpp, the geometry of the CPU back end's
 * row intervals). The host computes it vectorized rather than every work-group in scalar loops
 * (PoCL runs a work-group's work-items one after another), and it is tighter than the run test:
 * fewer whole rows are evaluated. */
#define BGK_REACH_FLOATS 7 /* x_min x_max ay az vy vz inv_vv */

/* The squared y-z distance from the row at (ry, rz) to the beam's clipped projection. */
inline float bgk_row_dyz2(float ry, float rz, float ay, float az, float vy, float vz, float inv_vv) {
  const float wy = ry - ay, wz = rz - az;
  float t = (wy * vy + wz * vz) * inv_vv;
  t = t < 0.0f ? 0.0f : (t > 1.0f ? 1.0f : t);
  const float ey = wy - t * vy, ez = wz - t * vz;
  return ey * ey + ez * ez;
}

inline void bgk_beam_reach(__local const float* s, float lo, float hi, __local float* out) {
  float s0 = s[6], s1 = s[7];
  if (!bgk_clip_to_slab(s[0], s[3], lo, hi, &s0, &s1) || !bgk_clip_to_slab(s[1], s[4], lo, hi, &s0, &s1) ||
      !bgk_clip_to_slab(s[2], s[5], lo, hi, &s0, &s1)) {
    out[0] = 1.0f;
    out[1] = -1.0f;
    return;
  }
  const float ax = s[0] + s0 * s[3], bx = s[0] + s1 * s[3];
  const float ay = s[1] + s0 * s[4], az = s[2] + s0 * s[5];
  const float vy = s[1] + s1 * s[4] - ay, vz = s[2] + s1 * s[5] - az;
  const float vv = vy * vy + vz * vz;
  out[0] = ax < bx ? ax : bx;
  out[1] = ax < bx ? bx : ax;
  out[2] = ay;
  out[3] = az;
  out[4] = vy;
  out[5] = vz;
  out[6] = vv > 0.0f ? 1.0f / vv : 0.0f;
}

inline bool bgk_beam_reaches_run(float x_lo, float x_hi, float ry, float rz, __local const float* c, float reach2) {
  if (c[0] > c[1]) return false;
  const float gx = bgk_gap(x_lo, x_hi, c[0], c[1]);
  return gx * gx + bgk_row_dyz2(ry, rz, c[2], c[3], c[4], c[5], c[6]) < reach2;
}

/* The body both kernels share; kernel_type is a compile-time constant after inlining. */
inline void bgk_integrate_job(const int kernel_type, __global float* pool, __global const BgkJob* jobs,
                              __global const float* hits, __global const float* beams,
                              __global const ulong* beam_rows, __global ulong* counts_out, const int n,
                              const float res, const float inv_ell2, const float sigma0, const float support2,
                              const int host_rows, const int layer, __local float* tile, __local float* reach_tile,
                              __local ulong* row_tile, __local ulong* scratch) {
  const BgkJob job = jobs[get_group_id(0)];
  const int run = min(n, BGK_RUN);
  const uint runs = (uint)(n * n * (n / run)); /* work-items' worth of cells in the block */
  const float half_size = 0.5f * res;
  const float reach2 = support2 * 1.002f; /* (1 + 0.1%)^2 */
  ulong within = 0, evaluated = 0;
  /* Every work-item takes part in every pass (and every barrier); in a block with fewer runs
   * than the work-group (depth 1 to 3) the extra ones compute nothing they keep. */
  for (uint base = 0; base < runs; base += get_local_size(0)) {
    const uint r = base + get_local_id(0);
    const bool active = r < runs;
    const int row = (int)r / (n / run), x0 = ((int)r % (n / run)) * run;
    const int ly = row % n, lz = row / n;
    const float cy = ly * res, cz = lz * res;
    const float x_lo = x0 * res, x_hi = (x0 + run - 1) * res;
    float alpha[BGK_RUN], beta[BGK_RUN];
    for (int i = 0; i < BGK_RUN; ++i) alpha[i] = beta[i] = 0.0f;
    /* Pairs within the support, per lane of the run (summed once per pass: a sum over the lanes
     * per observation was a horizontal reduction in every vectorized run loop), and pairs whose
     * distance was computed. */
    uint lane_count[BGK_RUN], computed = 0;
    for (int i = 0; i < BGK_RUN; ++i) lane_count[i] = 0u;

    for (uint t0 = 0; t0 < job.hit_count; t0 += BGK_TILE) {
      const uint m = bgk_next_tile(tile, hits, job.hit_begin, t0, job.hit_count, BGK_HIT_FLOATS, 0, row_tile);
      for (uint h = 0; h < m; ++h) {
        const float px = tile[BGK_HIT_FLOATS * h], py = tile[BGK_HIT_FLOATS * h + 1],
                    pz = tile[BGK_HIT_FLOATS * h + 2];
        if (kernel_type == BGK_KERNEL_BOX) {
          for (int i = 0; i < BGK_RUN; ++i) {
            const float k = bgk_box_kernel_point((x0 + i) * res, cy, cz, half_size, px, py, pz);
            alpha[i] += k;
            lane_count[i] += (i < run && k > 0.0f) ? 1u : 0u;
          }
          computed += (uint)run;
          continue;
        }
        const float dy = cy - py, dz = cz - pz;
        const float dyz2 = dy * dy + dz * dz;
        if (dyz2 >= support2 || !bgk_hit_reaches_run(x_lo, x_hi, dyz2, px, reach2)) continue;
        computed += (uint)run;
        for (int i = 0; i < BGK_RUN; ++i) {
          const float dx = (x0 + i) * res - px;
          const float d2 = dx * dx + dyz2;
          alpha[i] += bgk_sparse_kernel_d2(d2, inv_ell2, sigma0);
          lane_count[i] += (i < run && d2 < support2) ? 1u : 0u;
        }
      }
    }

    for (uint t0 = 0; t0 < job.beam_count; t0 += BGK_TILE) {
      const uint m = bgk_next_tile(tile, beams, job.beam_begin, t0, job.beam_count, BGK_BEAM_FLOATS,
                                   host_rows ? beam_rows : 0, row_tile);
      if (kernel_type != BGK_KERNEL_BOX && !host_rows) {
        const float reach = sqrt(reach2), block_hi = (n - 1) * res + reach;
        for (uint b = get_local_id(0); b < m; b += get_local_size(0))
          bgk_beam_reach(tile + BGK_BEAM_FLOATS * b, -reach, block_hi, reach_tile + BGK_REACH_FLOATS * b);
        barrier(CLK_LOCAL_MEM_FENCE);
      }
      for (uint b = 0; b < m; ++b) {
        __local const float* s = tile + BGK_BEAM_FLOATS * b;
        if (kernel_type == BGK_KERNEL_BOX) {
          for (int i = 0; i < BGK_RUN; ++i) {
            const float k = bgk_box_kernel_segment((x0 + i) * res, cy, cz, half_size, s[0] + s[6] * s[3],
                                                   s[1] + s[6] * s[4], s[2] + s[6] * s[5], s[0] + s[7] * s[3],
                                                   s[1] + s[7] * s[4], s[2] + s[7] * s[5]);
            beta[i] += k;
            lane_count[i] += (i < run && k > 0.0f) ? 1u : 0u;
          }
          computed += (uint)run;
          continue;
        }
        if (host_rows) {
          /* The run is the whole row: its bit is the test. */
          if (!((row_tile[b] >> row) & 1ul)) continue;
        } else if (!bgk_beam_reaches_run(x_lo, x_hi, cy, cz, reach_tile + BGK_REACH_FLOATS * b, reach2)) {
          continue;
        }
        computed += (uint)run;
        for (int i = 0; i < BGK_RUN; ++i) {
          const float d2 =
              bgk_anchored_segment_dist2((x0 + i) * res, cy, cz, s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7]);
          beta[i] += bgk_sparse_kernel_d2(d2, inv_ell2, sigma0);
          lane_count[i] += (i < run && d2 < support2) ? 1u : 0u;
        }
      }
    }

    if (active && (layer < 0 || lz == layer)) { /* a planar map keeps its layer only */
      const size_t first = 2 * ((size_t)job.slot * (size_t)(n * n * n) + (size_t)(row * n + x0));
      for (int i = 0; i < run; ++i) {
        pool[first + 2 * i] += alpha[i];
        pool[first + 2 * i + 1] += beta[i];
      }
      for (int i = 0; i < BGK_RUN; ++i) within += lane_count[i];
      evaluated += computed;
    }
  }
  within = bgk_group_sum(within, scratch);
  evaluated = bgk_group_sum(evaluated, scratch);
  if (get_local_id(0) == 0) {
    counts_out[2 * get_group_id(0)] = evaluated;
    counts_out[2 * get_group_id(0) + 1] = within;
  }
}

/* Local memory: a tile of beams (the larger record) and the reduction scratch, sized by the
 * largest work-group the host will launch (it passes -DBGK_MAX_GROUP=...). */
#ifndef BGK_MAX_GROUP
#error "build with -DBGK_MAX_GROUP=<largest work-group size>"
#endif

/* beam_rows: per beam, the host's row bits (read only when host_rows is set: 8^3 blocks, sparse kernel).
 * layer: a planar map's layer of cells inside the block (its z), whose cells alone are added to the
 * pool; -1 for every layer. */
__kernel void bgk_block_sparse(__global float* pool, __global const BgkJob* jobs, __global const float* hits,
                               __global const float* beams, __global const ulong* beam_rows,
                               __global ulong* counts_out, const int n, const float res, const float inv_ell2,
                               const float sigma0, const float support2, const int host_rows,
                               const int layer) {
  __local float tile[BGK_TILE * BGK_BEAM_FLOATS];
  __local float reach_tile[BGK_TILE * BGK_REACH_FLOATS];
  __local ulong row_tile[BGK_TILE];
  __local ulong scratch[BGK_MAX_GROUP];
  bgk_integrate_job(BGK_KERNEL_SPARSE, pool, jobs, hits, beams, beam_rows, counts_out, n, res, inv_ell2, sigma0,
                    support2, host_rows, layer, tile, reach_tile, row_tile, scratch);
}

/* One hit against the row pair whose first row is `row` (z * 8 + y, y even), in the 16 lanes of
 * cx (x offsets of a row, twice): adds the kernel values to alpha and -1 per pair within the
 * support to within, when a row of the pair is within reach; returns whether it was. */
inline uint bgk_hit_row_pair(int row, float px, float py, float pz, float16 cx, float res, float inv_ell2,
                             float sigma0, float support2, float16* alpha, int16* within) {
  const float reach2 = support2 * 1.002f; /* as in bgk_integrate_job */
  const float dy0 = (row & 7) * res - py, dy1 = ((row & 7) + 1) * res - py, dz = (row >> 3) * res - pz;
  const float dyz2_0 = dy0 * dy0 + dz * dz, dyz2_1 = dy1 * dy1 + dz * dz;
  const bool near0 = dyz2_0 < support2 && bgk_hit_reaches_run(0.0f, 7 * res, dyz2_0, px, reach2);
  const bool near1 = dyz2_1 < support2 && bgk_hit_reaches_run(0.0f, 7 * res, dyz2_1, px, reach2);
  if (!near0 && !near1) return 0u;
  const int16 lane = (int16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  const float16 dx = cx - px;
  const float16 d2 = dx * dx + select((float16)(dyz2_0), (float16)(dyz2_1), lane >= 8);
  *alpha += bgk_sparse_kernel_d2_16(d2, inv_ell2, sigma0);
  *within += d2 < support2;
  return 1u;
}

/* 8^3 blocks with the sparse kernel, for CPU devices: each of 32 work-items owns rows 2p and
 * 2p + 1 of the block (16 consecutive cells; lane i: x = i & 7, y = 2 (p & 3) + (i >> 3),
 * z = p >> 2) and evaluates an observation that reaches either row in explicit 16-wide vectors,
 * which PoCL compiles to 512-bit instructions where the CPU has them (it vectorizes the 8-cell
 * runs of bgk_block_sparse at 256 bits), testing one pair of row bits per beam instead of one bit
 * per row. The CPU back end evaluates the same row pairs. When an observation passes the test of
 * only one of the two rows, the other row has no cell within the support, so its lanes add exactly
 * 0; every cell gets the same expressions in the same order as in bgk_block_sparse: the same sums.
 * Launched with 32 work-items, with the arguments of bgk_block_sparse (n is 8, host_rows set). */
__kernel void bgk_block_sparse_pairs(__global float* pool, __global const BgkJob* jobs, __global const float* hits,
                                     __global const float* beams, __global const ulong* beam_rows,
                                     __global ulong* counts_out, const int n, const float res, const float inv_ell2,
                                     const float sigma0, const float support2, const int host_rows,
                                     const int layer) {
  __local float tile[BGK_TILE * BGK_BEAM_FLOATS];
  __local ulong row_tile[BGK_TILE];
  __local ulong scratch[BGK_MAX_GROUP];
  (void)n;
  (void)host_rows;
  const BgkJob job = jobs[get_group_id(0)];
  const int row = 2 * (int)get_local_id(0); /* the pair's first row, z * 8 + y with y even */
  const int16 lane = (int16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  const float16 cx = convert_float16(lane & 7) * res;
  const float16 cy = convert_float16((row & 7) + (lane >> 3)) * res;
  const float cz = (row >> 3) * res;
  float16 alpha = 0.0f, beta = 0.0f;
  int16 within = 0; /* minus the pairs within the support, per lane (a comparison is -1 when true) */
  uint computed = 0;

  for (uint t0 = 0; t0 < job.hit_count; t0 += BGK_TILE) {
    const uint m = bgk_next_tile(tile, hits, job.hit_begin, t0, job.hit_count, BGK_HIT_FLOATS, 0, row_tile);
    for (uint h = 0; h < m; ++h) {
      __local const float* p = tile + BGK_HIT_FLOATS * h;
      if (layer < 0 || (row >> 3) == layer) /* a planar map's layer only */
        computed += 16u * bgk_hit_row_pair(row, p[0], p[1], p[2], cx, res, inv_ell2, sigma0, support2, &alpha, &within);
    }
  }

  for (uint t0 = 0; t0 < job.beam_count; t0 += BGK_TILE) {
    const uint m =
        bgk_next_tile(tile, beams, job.beam_begin, t0, job.beam_count, BGK_BEAM_FLOATS, beam_rows, row_tile);
    for (uint b = 0; b < m; ++b) {
      if (!((row_tile[b] >> row) & 3ul)) continue;
      __local const float* s = tile + BGK_BEAM_FLOATS * b;
      computed += 16u;
      const float16 d2 = bgk_offset_segment_dist2_16(cx - s[0], cy - s[1], (float16)(cz - s[2]), s[3], s[4], s[5],
                                                     s[6], s[7]);
      beta += bgk_sparse_kernel_d2_16(d2, inv_ell2, sigma0);
      within += d2 < support2;
    }
  }

  float alpha_cells[16], beta_cells[16];
  vstore16(alpha, 0, alpha_cells);
  vstore16(beta, 0, beta_cells);
  const size_t first = 2 * ((size_t)job.slot * 512 + (size_t)(row * 8));
  if (layer < 0 || (row >> 3) == layer) /* a planar map keeps its layer only */
    for (int i = 0; i < 16; ++i) {
      pool[first + 2 * i] += alpha_cells[i];
      pool[first + 2 * i + 1] += beta_cells[i];
    }
  int within_cells[16];
  vstore16(within, 0, within_cells);
  ulong near = 0;
  for (int i = 0; i < 16; ++i) near += (ulong)(-within_cells[i]);
  near = bgk_group_sum(near, scratch);
  const ulong evaluated = bgk_group_sum(computed, scratch);
  if (get_local_id(0) == 0) {
    counts_out[2 * get_group_id(0)] = evaluated;
    counts_out[2 * get_group_id(0) + 1] = near;
  }
}

/* One work-item per 8^3 block, for CPU devices (PoCL): the CPU back end's loops in OpenCL C. A
 * work-group of bgk_block_sparse_pairs tests every beam once per row pair (32 tests), and each
 * work-item's beams form chains of dependent steps with a mispredicted branch between them.
 * Here the block's 32 row pairs accumulate in private memory; a batch of beams is first listed as
 * (beam, row pair) items from the host's row bits, then the items are evaluated in one loop
 * without branches, software pipelined in three stages (distances of item i, square roots of
 * item i - 1, the kernel of item i - 2, added to its pair): each stage's operands come from an
 * earlier iteration. Every cell gets its hits, then its beams, in the host's order, with the same
 * expressions: the same sums as the other kernels. */
#define BGK_ITEM_BATCH 64 /* beams listed at a time: up to 64 * 32 items */

__kernel void bgk_block_sparse_whole(__global float* pool, __global const BgkJob* jobs, __global const float* hits,
                                     __global const float* beams, __global const ulong* beam_rows,
                                     __global ulong* counts_out, const int n, const float res, const float inv_ell2,
                                     const float sigma0, const float support2, const int host_rows,
                                     const int layer) {
  (void)n;
  (void)host_rows;
  const BgkJob job = jobs[get_group_id(0)];
  const int16 lane = (int16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  const float16 cx = convert_float16(lane & 7) * res;
  float16 alpha[32], beta[32];
  for (int p = 0; p < 32; ++p) alpha[p] = beta[p] = 0.0f;
  int16 within = 0; /* minus the pairs within the support, per lane */
  ulong computed = 0;

  /* Hits, as bgk_block_sparse_pairs' work-items do, one row pair after another. */
  __global const float* hit = hits + (size_t)job.hit_begin * BGK_HIT_FLOATS;
  for (uint h = 0; h < job.hit_count; ++h, hit += BGK_HIT_FLOATS) {
    for (int p = 0; p < 32; ++p)
      if (layer < 0 || (p >> 2) == layer) /* a planar map's layer only */
        computed += 16u * bgk_hit_row_pair(2 * p, hit[0], hit[1], hit[2], cx, res, inv_ell2, sigma0, support2,
                                           &alpha[p], &within);
  }

  /* Beams. An item is beam << 5 | row pair; two extra items (beam 0, pair 0) end the pipeline.
   * Row pair p's cells sit at y = 2 (p & 3) + (lane >> 3) and z = p >> 2, computed once here. */
  float16 cy[4];
  float cz[8];
  for (int j = 0; j < 4; ++j) cy[j] = convert_float16(2 * j + (lane >> 3)) * res;
  for (int z = 0; z < 8; ++z) cz[z] = z * res;
  uint items[BGK_ITEM_BATCH * 32 + 2];
  for (uint b0 = 0; b0 < job.beam_count; b0 += BGK_ITEM_BATCH) {
    const uint batch = min((uint)BGK_ITEM_BATCH, job.beam_count - b0);
    __global const float* batch_beams = beams + (size_t)(job.beam_begin + b0) * BGK_BEAM_FLOATS;
    __global const ulong* batch_rows = beam_rows + job.beam_begin + b0;
    uint count = 0;
    for (uint b = 0; b < batch; ++b) {
      ulong pairs = (batch_rows[b] | batch_rows[b] >> 1) & 0x5555555555555555ul; /* bit 2p: row 2p or 2p + 1 */
      while (pairs) {
        const uint row = 63u - (uint)clz(pairs & (0ul - pairs)); /* the lowest set bit */
        items[count++] = b << 5 | row >> 1;
        pairs &= pairs - 1ul;
      }
    }
    items[count] = items[count + 1] = 0;
    computed += 16u * count;
    float16 d2_1 = INFINITY, d2_2 = INFINITY, r_2 = INFINITY;
    uint pair_1 = 0, pair_2 = 0;
    for (uint i = 0; i < count + 2; ++i) {
      const uint pair = items[i] & 31u;
      __global const float* s = batch_beams + (items[i] >> 5) * BGK_BEAM_FLOATS;
      const float16 d2 = bgk_offset_segment_dist2_16(cx - s[0], cy[pair & 3u] - s[1], (float16)(cz[pair >> 2] - s[2]),
                                                     s[3], s[4], s[5], s[6], s[7]);
      const float16 r_1 = sqrt(d2_1 * inv_ell2); /* as bgk_sparse_kernel_d2 */
      /* Item i - 2; in the first two iterations r = +inf adds 0 to pair 0 and counts nothing. */
      beta[pair_2] += bgk_sparse_kernel_of_ratio_16(r_2, sigma0);
      within += d2_2 < support2;
      d2_2 = d2_1, r_2 = r_1, pair_2 = pair_1;
      d2_1 = d2, pair_1 = pair;
    }
  }

  const size_t first = 2 * (size_t)job.slot * 512;
  for (int p = 0; p < 32; ++p) {
    if (layer >= 0 && (p >> 2) != layer) continue; /* a planar map keeps its layer only */
    float alpha_cells[16], beta_cells[16];
    vstore16(alpha[p], 0, alpha_cells);
    vstore16(beta[p], 0, beta_cells);
    for (int i = 0; i < 16; ++i) {
      pool[first + 2 * (16 * p + i)] += alpha_cells[i];
      pool[first + 2 * (16 * p + i) + 1] += beta_cells[i];
    }
  }
  int within_cells[16];
  vstore16(within, 0, within_cells);
  ulong near = 0;
  for (int i = 0; i < 16; ++i) near += (ulong)(-within_cells[i]);
  counts_out[2 * get_group_id(0)] = computed;
  counts_out[2 * get_group_id(0) + 1] = near;
}

__kernel void bgk_block_box(__global float* pool, __global const BgkJob* jobs, __global const float* hits,
                            __global const float* beams, __global const ulong* beam_rows, __global ulong* counts_out,
                            const int n, const float res, const float inv_ell2, const float sigma0,
                            const float support2, const int host_rows, const int layer) {
  __local float tile[BGK_TILE * BGK_BEAM_FLOATS];
  __local ulong scratch[BGK_MAX_GROUP];
  bgk_integrate_job(BGK_KERNEL_BOX, pool, jobs, hits, beams, beam_rows, counts_out, n, res, inv_ell2, sigma0,
                    support2, 0, layer, tile, tile, scratch, scratch);
}

/* The cells of the pool's blocks `slots[0..)` copied into `packed`, block after block
 * (bgk_pool_gather), or from it back into the pool (bgk_pool_scatter), bits as they are: the host
 * reads and writes the blocks a scan touches (the expected sub-map) in one transfer each way
 * rather than one per run of consecutive slots. Dimension 0 is the cell, 1 the block: a
 * work-group copies contiguous cells (a plain loop on a CPU device). */
__kernel void bgk_pool_gather(__global const uint2* pool, __global const uint* slots, __global uint2* packed) {
  const size_t cell = get_global_id(0), cells = get_global_size(0), block = get_global_id(1);
  packed[block * cells + cell] = pool[(size_t)slots[block] * cells + cell];
}

__kernel void bgk_pool_scatter(__global uint2* pool, __global const uint* slots, __global const uint2* packed) {
  const size_t cell = get_global_id(0), cells = get_global_size(0), block = get_global_id(1);
  pool[(size_t)slots[block] * cells + cell] = packed[block * cells + cell];
}

/* Forgetting: each cell of the pool's blocks `slots[0..)` decayed toward the prior by its block's
 * factor (bgk_decayed, as the host decays), before the scan's kernels add to them. Dimension 0 is
 * the cell, 1 the block. */
__kernel void bgk_pool_decay(__global BgkCell* pool, __global const uint* slots, __global const float* factors,
                             const float prior_alpha, const float prior_beta) {
  const size_t cell = get_global_id(0), cells = get_global_size(0), block = get_global_id(1);
  __global BgkCell* c = pool + (size_t)slots[block] * cells + cell;
  const float f = factors[block];
  c->alpha = bgk_decayed(c->alpha, prior_alpha, f);
  c->beta = bgk_decayed(c->beta, prior_beta, f);
}
