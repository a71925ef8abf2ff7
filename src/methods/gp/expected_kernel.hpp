// The expected covariance of GP inputs with Gaussian position uncertainty (GPPOL, O'Callaghan &
// Ramos IJRR 2012; the expected kernel of the WGPOM paper): E[k(|d|)] for a difference of inputs
// d ~ N(m, S). gpom and wgpom use it under --pose-fusion kernel (docs/ALGORITHM.md, "Pose
// uncertainty"). Internal header of those methods (tests include it).
#pragma once

#include <vector>

#include "methods/gp/gp_regression.hpp"

namespace bgkmap {

// A symmetric 3x3 covariance of a position (m^2).
struct PositionCovariance {
  double xx = 0, xy = 0, xz = 0, yy = 0, yz = 0, zz = 0;

  bool is_zero() const { return xx == 0 && xy == 0 && xz == 0 && yy == 0 && yz == 0 && zz == 0; }
  PositionCovariance operator+(const PositionCovariance& o) const {
    return {xx + o.xx, xy + o.xy, xz + o.xz, yy + o.yy, yz + o.yz, zz + o.zz};
  }
};

// E[k(|d|)], d ~ N(m, S), for the covariance of `hp`:
// - S = 0: gp_kernel(|m|), the plain kernel bit for bit;
// - squared exponential: the closed form (IJRR eq. 19)
//     s2 |I + S / l^2|^-1/2 exp(-1/2 m^T (l^2 I + S)^-1 m);
// - Matern 3/2 and sparse: a Gauss-Hermite product rule of `order` nodes per axis over the first
//   `dims` axes (2: a planar map, where S's z rows are 0 and m.z is kept; 3: 3-D), its Gaussian
//   matched to the product of N(m, S) and a Gaussian as wide as the kernel (expected_kernel.cpp),
//   so that an S wider than the kernel still puts the nodes on it.
// The stationary covariances only: the constructor throws std::invalid_argument for kNeuralNetwork.
class ExpectedKernel {
 public:
  ExpectedKernel(const GpHyperParams& hp, int dims, int order);

  double operator()(const Vec3d& m, const PositionCovariance& s) const;

  const GpHyperParams& hyperparameters() const { return hp_; }
  int dims() const { return dims_; }
  int order() const { return order_; }

 private:
  GpHyperParams hp_;
  int dims_, order_;
  double kernel_variance_ = 0;  // v of the matched rule
  std::vector<double> node_z_;   // dims_ standard coordinates per node (sqrt(2) x_i)
  std::vector<double> node_w_;   // product weights / pi^(dims/2)
};

// The product rule's nodes per axis gpom uses in 2-D and in 3-D (chosen by the accuracy/cost
// measurement in docs/ALGORITHM.md, "Pose uncertainty").
constexpr int kExpectedKernelOrder2d = 8, kExpectedKernelOrder3d = 6;

}  // namespace bgkmap
