/* Weighted Gram matrices of sparse rows, one work-group per block (OpenCL C 1.2 with cl_khr_fp64):
 *   gram_b = sum_r weight_r phi_r phi_r^T,  rhs_b = sum_r target_r phi_r
 * over the rows r of block b, each row a few (column, value) entries with columns in [0, m).
 * The Bayesian Hilbert map's Phi^T Lambda Phi and Phi^T (y - 1/2) (src/integrate/block_gram.hpp).
 *
 * Work-item j owns column j of gram_b (and rhs_b[j]); the rows are staged, chunk at a time, as a
 * dense chunk x m tile in local memory, so that a work-item finds its phi_j in one read. Where
 * phi_j != 0 it adds (weight phi_j) phi_i to every entry i of the row: the same products, summed in
 * the same row order, as the CPU reference (block_gram.cpp), so both give the same bits. No entry
 * has two owners, so no atomics. Output column-major: gram_b(i, j) at (b - first) m^2 + i + j m. */

#pragma OPENCL EXTENSION cl_khr_fp64 : enable
/* Contraction into fma would round differently from the host (built with -ffp-contract=off). */
#pragma OPENCL FP_CONTRACT OFF

/* chunk: rows staged per tile (the host fits chunk x m doubles into local memory: 32 x 64 is
 * 16 KiB with 8 x 8 blocks). */
__kernel void block_gram(const int m, const uint first_block, const uint chunk, __global const uint* block_row_begin,
                         __global const uint* row_begin, __global const int* column,
                         __global const double* value, __global const double* weight,
                         __global const double* target, __global double* gram, __global double* rhs,
                         __local double* tile) {
  const uint b = first_block + (uint)get_group_id(0);
  const int lid = (int)get_local_id(0), size = (int)get_local_size(0);
  __global double* g = gram + (size_t)get_group_id(0) * (size_t)m * (size_t)m;
  __global double* h = rhs + (size_t)get_group_id(0) * (size_t)m;
  for (int e = lid; e < m * m; e += size) g[e] = 0.0;
  for (int j = lid; j < m; j += size) h[j] = 0.0;
  const uint r0 = block_row_begin[b], r1 = block_row_begin[b + 1];
  for (uint c = r0; c < r1; c += chunk) {
    const int n = (int)min(chunk, r1 - c);
    for (int i = lid; i < n * m; i += size) tile[i] = 0.0;
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int r = lid; r < n; r += size)
      for (uint e = row_begin[c + r]; e < row_begin[c + r + 1]; ++e) tile[r * m + column[e]] = value[e];
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int j = lid; j < m; j += size) {
      __global double* gj = g + (size_t)j * (size_t)m;
      double hj = h[j];
      for (int r = 0; r < n; ++r) {
        const double phi_j = tile[r * m + j];
        if (phi_j == 0.0) continue;
        const double scaled = weight[c + r] * phi_j;
        for (uint e = row_begin[c + r]; e < row_begin[c + r + 1]; ++e) gj[column[e]] += scaled * value[e];
        hj += phi_j * target[c + r];
      }
      h[j] = hj;
    }
    barrier(CLK_LOCAL_MEM_FENCE);
  }
}
