// The counting sensor model baseline (internal header; see counting_method.cpp).
#pragma once

#include <memory>

#include "bgkmap/methods/method.hpp"

namespace bgkmap {

std::unique_ptr<MappingMethod> make_counting_method(const BuildParams& params);

}  // namespace bgkmap
