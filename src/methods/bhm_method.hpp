// The Bayesian Hilbert map method (internal header; see bhm_method.cpp).
#pragma once

#include <memory>

#include "bgkmap/methods/method.hpp"

namespace bgkmap {

// threads <= 0: OpenMP's default (all cores).
std::unique_ptr<MappingMethod> make_bhm_method(const BuildParams& params, const MethodParams& method_params,
                                               int threads);

}  // namespace bgkmap
