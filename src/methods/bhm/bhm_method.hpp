// The Bayesian Hilbert map method (internal header; see bhm_method.cpp).
#pragma once

#include <memory>

#include "bgkmap/methods/method.hpp"

namespace bgkmap {

// backend: where each block's Phi^T Lambda Phi is summed (cpu, opencl, auto: integrate/block_gram.hpp);
// its threads <= 0: OpenMP's default (all cores).
std::unique_ptr<MappingMethod> make_bhm_method(const BuildParams& params, const MethodParams& method_params,
                                               const BackendOptions& backend);

}  // namespace bgkmap
