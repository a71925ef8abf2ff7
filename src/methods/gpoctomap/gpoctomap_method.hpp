// The GPOctoMap baseline (internal header; see gpoctomap_method.cpp).
#pragma once

#include <memory>

#include "bgkmap/methods/method.hpp"

namespace bgkmap {

// threads <= 0: OpenMP's default (all cores).
std::unique_ptr<MappingMethod> make_gpoctomap_method(const BuildParams& params, const MethodParams& method_params,
                                                     int threads);

}  // namespace bgkmap
