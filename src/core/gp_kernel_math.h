/* The covariance functions of the GP methods (gpom, wgpom, gpoctomap) as functions of the distance,
 * in double, shared by the C++ code (methods/gp/gp_regression.cpp) and the OpenCL kernel that solves
 * batches of local models (kernels/local_gp.cl). Written in the common subset of C++17 and
 * OpenCL C 1.2, as core/bgk_math.h is: plain doubles, no references. */
#ifndef BGKMAP_CORE_GP_KERNEL_MATH_H
#define BGKMAP_CORE_GP_KERNEL_MATH_H

#ifdef __OPENCL_C_VERSION__
#define GP_FN inline
#define GP_EXP(x) exp(x)
#define GP_SIN(x) sin(x)
#define GP_COS(x) cos(x)
#else
#include <cmath>
#define GP_FN inline
#define GP_EXP(x) std::exp(x)
#define GP_SIN(x) std::sin(x)
#define GP_COS(x) std::cos(x)
#endif

/* Covariance selector values, shared with the host's GpCovariance enum. */
#define GP_COVARIANCE_SPARSE 0
#define GP_COVARIANCE_MATERN32 1
#define GP_COVARIANCE_SQUARED_EXPONENTIAL 2
/* The neural-network covariance is a function of two inputs, not of their distance: not here
 * (methods/gp/gp_regression.cpp evaluates it, on the CPU only). */
#define GP_COVARIANCE_NEURAL_NETWORK 3

/* Sparse (Melkumyan & Ramos; closed form, zero at and beyond ell):
 *   k(d) = s2 [(2 + cos(2 pi d/l))/3 (1 - d/l) + sin(2 pi d/l)/(2 pi)] for d < l, else 0.
 * Matern nu = 3/2:  k(d) = s2 (1 + sqrt(3) d/l) exp(-sqrt(3) d/l).
 * Squared exponential: k(d) = s2 exp(-d^2 / (2 l^2)). */
GP_FN double gp_kernel_value(int covariance, double d, double ell, double signal_var) {
  if (covariance == GP_COVARIANCE_MATERN32) {
    const double r = 1.7320508075688772 * d / ell;
    return signal_var * (1 + r) * GP_EXP(-r);
  }
  if (covariance == GP_COVARIANCE_SQUARED_EXPONENTIAL) {
    const double x = d / ell;
    return signal_var * GP_EXP(-0.5 * x * x);
  }
  if (d >= ell) return 0;
  const double two_pi = 6.283185307179586, x = d / ell;
  return signal_var * ((2 + GP_COS(two_pi * x)) / 3 * (1 - x) + GP_SIN(two_pi * x) / two_pi);
}

#endif
