// Batches of small GP regressions, one query per local model: for model q with n training inputs,
// labels y and query x*, the mean k*^T (K + sn^2 I)^-1 y and variance k(0) - k*^T (K + sn^2 I)^-1 k*
// (gpom's and wgpom's per-cell local models, methods/gpom/gpom_method.cpp). Many small dense Cholesky
// solves of the same shape: regular work for an OpenCL device (kernels/local_gp.cl, one
// work-group per model). The CPU path is the methods' own (methods/gp/gp_regression.cpp, Eigen); the
// device agrees with it to rounding (tests/test_local_gp.cpp), not bit for bit. Internal to the
// library.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/integrate/integrator.hpp"

namespace bgkmap {

struct LocalGpBatch {
  int max_n = 0;                // training inputs per model at most: the stride below
  std::vector<int32_t> count;   // per model: its training inputs
  std::vector<double> train;    // per model max_n x (x, y, z); the first `count` used
  std::vector<double> labels;   // per model max_n
  std::vector<double> query;    // per model (x, y, z)
  size_t size() const { return count.size(); }
  // One more model (train.size() <= max_n), or every model of `other` (of the same max_n).
  void add(const std::vector<Vec3d>& train, const std::vector<double>& labels, const Vec3d& query);
  void append(const LocalGpBatch& other);
};

// The covariance: core/gp_kernel_math.h's selector, length scale, signal and noise variances.
struct LocalGpCovariance {
  int covariance = 0;
  double ell_m = 0, signal_var = 0, noise_var = 0;
};

class LocalGpDevice {
 public:
  virtual ~LocalGpDevice() = default;
  // kind: where predict() solves; kCpu (by choice, or since the device failed, note saying why):
  // the caller solves the models on its own CPU path.
  virtual BackendInfo info() const = 0;
  // Every model's mean and variance (NaN for a kernel matrix that is not positive definite).
  // False when nothing was solved here (a CPU engine, or the device failed: info().kind is kCpu
  // from then on): the caller solves them itself.
  virtual bool predict(const LocalGpBatch& batch, const LocalGpCovariance& covariance, double* mean,
                       double* variance) = 0;
};

// The engine that solves local models on `device`: its OpenCL device when the device is a GPU
// with double precision, or OpenCL was asked for (on a CPU device, PoCL, the CPU path is faster:
// docs/BENCHMARKS.md, "gpom: the local models on OpenCL"); else a CPU engine whose predict() leaves
// the models to the caller.
std::unique_ptr<LocalGpDevice> make_local_gp_device(const ComputeDevice& device);

namespace opencl_detail {
// The OpenCL device the options' filter selects; throws OpenClUnavailable saying why not.
std::unique_ptr<LocalGpDevice> make_opencl_local_gp(const BackendOptions& options);
}  // namespace opencl_detail

}  // namespace bgkmap
