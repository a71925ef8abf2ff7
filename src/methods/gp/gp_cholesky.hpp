// The Cholesky factor of a GP's training covariance, for the GP methods' sources (Eigen stays out
// of the headers tests and other sources include).
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <vector>

#include "methods/gp/gp_regression.hpp"

namespace bgkmap {

// L L^T = K + sn^2 I over the training points (k of their distances, gp_kernel; with `uncertain`,
// the expected covariances of InputUncertainty); throws GpNotPositiveDefinite when it is
// not positive definite.
Eigen::LLT<Eigen::MatrixXd> gp_factor(const std::vector<Vec3d>& train, const GpHyperParams& hp,
                                      const InputUncertainty* uncertain = nullptr);

}  // namespace bgkmap
