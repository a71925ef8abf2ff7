// The counting sensor model baseline (internal header; see counting_method.cpp).
#pragma once

#include <memory>

#include "bgkmap/methods/method.hpp"

namespace bgkmap {

// forget_half_life: in scans, 0 = off (map/forgetting.hpp).
std::unique_ptr<MappingMethod> make_counting_method(const BuildParams& params, double forget_half_life);

}  // namespace bgkmap
