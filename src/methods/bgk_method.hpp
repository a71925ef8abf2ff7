// BGKOctoMap (T-RO 2019 baseline; internal header, see bgk_method.cpp).
#pragma once

#include <memory>

#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/methods/method.hpp"

namespace bgkmap {

// Free points sampled along a free segment: origin + k * spacing along it, k = 1, 2, ... while
// within its length (the origin itself is not a sample). Exposed for tests.
void sample_free_points(const Vec3f& origin, const Vec3f& free_end, double spacing_m, std::vector<Vec3f>& out);

std::unique_ptr<MappingMethod> make_bgk_method(const BuildParams& params, const MethodParams& method_params,
                                               std::unique_ptr<Integrator> integrator);

}  // namespace bgkmap
