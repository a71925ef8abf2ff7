/* GP regression on a batch of local models, one work-group per model (OpenCL C 1.2 with
 * cl_khr_fp64): for model q with n training inputs x_i, labels y_i and one query x*,
 *   K = k(x_i, x_j) + sn^2 I = L L^T,  v = L^-1 k*,  w = L^-1 y,
 *   mean = v . w,  variance = k(0) - v . v
 * (the mean k*^T K^-1 y and variance k(0) - k*^T K^-1 k* of gpom's local models,
 * src/integrate/local_gp_batch.hpp). The kernel values are core/gp_kernel_math.h's, the host's.
 * K, v and w live in local memory; the Cholesky factorisation goes column by column (the column
 * scaled, then the trailing triangle updated by all work-items), the two forward solves likewise.
 * A matrix that is not positive definite gives NaN (the host then says so). */

#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#pragma OPENCL FP_CONTRACT OFF

#include "core/gp_kernel_math.h"

__kernel void local_gp_predict(const int max_n, const int covariance, const double ell, const double signal_var,
                               const double noise_var, __global const int* count, __global const double* train,
                               __global const double* labels, __global const double* query, __global double* mean,
                               __global double* variance, __local double* chol, __local double* v,
                               __local double* w, __local int* failed) {
  const size_t q = get_group_id(0);
  const int lid = (int)get_local_id(0), size = (int)get_local_size(0);
  const int n = count[q];
  __global const double* x = train + q * (size_t)max_n * 3;
  __global const double* y = labels + q * (size_t)max_n;
  const double qx = query[3 * q], qy = query[3 * q + 1], qz = query[3 * q + 2];
  if (lid == 0) *failed = 0;
  /* The lower triangle of K (row-major, stride n), k* in v and y in w. */
  for (int e = lid; e < n * n; e += size) {
    const int i = e / n, j = e - i * n;
    if (j > i) continue;
    const double dx = x[3 * i] - x[3 * j], dy = x[3 * i + 1] - x[3 * j + 1], dz = x[3 * i + 2] - x[3 * j + 2];
    chol[e] = gp_kernel_value(covariance, sqrt(dx * dx + dy * dy + dz * dz), ell, signal_var) + (i == j ? noise_var : 0.0);
  }
  for (int i = lid; i < n; i += size) {
    const double dx = x[3 * i] - qx, dy = x[3 * i + 1] - qy, dz = x[3 * i + 2] - qz;
    v[i] = gp_kernel_value(covariance, sqrt(dx * dx + dy * dy + dz * dz), ell, signal_var);
    w[i] = y[i];
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  for (int j = 0; j < n; ++j) {
    if (lid == 0) {
      const double d = chol[j * n + j];
      if (!(d > 0)) *failed = 1;
      chol[j * n + j] = sqrt(d);
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    const double pivot = chol[j * n + j];
    for (int i = j + 1 + lid; i < n; i += size) chol[i * n + j] /= pivot;
    barrier(CLK_LOCAL_MEM_FENCE);
    const int rest = n - j - 1;
    for (int e = lid; e < rest * rest; e += size) {
      const int r = j + 1 + e / rest, c = j + 1 + e % rest;
      if (c <= r) chol[r * n + c] -= chol[r * n + j] * chol[c * n + j];
    }
    barrier(CLK_LOCAL_MEM_FENCE);
  }
  for (int j = 0; j < n; ++j) {
    if (lid == 0) {
      v[j] /= chol[j * n + j];
      w[j] /= chol[j * n + j];
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int i = j + 1 + lid; i < n; i += size) {
      v[i] -= chol[i * n + j] * v[j];
      w[i] -= chol[i * n + j] * w[j];
    }
    barrier(CLK_LOCAL_MEM_FENCE);
  }
  if (lid == 0) {
    double vw = 0, vv = 0;
    for (int i = 0; i < n; ++i) vw += v[i] * w[i], vv += v[i] * v[i];
    mean[q] = *failed ? NAN : vw;
    variance[q] = *failed ? NAN : gp_kernel_value(covariance, 0.0, ell, signal_var) - vv;
  }
}
