// The GPOM and WGPOM methods (internal header; see gpom_method.cpp).
#pragma once

#include <memory>
#include <optional>

#include "bgkmap/methods/method.hpp"
#include "methods/warped_gp.hpp"

namespace bgkmap {

// threads <= 0: OpenMP's default (all cores).
std::unique_ptr<MappingMethod> make_gpom_method(const BuildParams& params, const MethodParams& method_params,
                                                int threads);

// wgpom: gpom's local models with warped labels. `warp` given: that warp; else the warp is learned
// (method_params.wgp_terms tanh terms) when the map is first evaluated.
std::unique_ptr<MappingMethod> make_wgpom_method(const BuildParams& params, const MethodParams& method_params,
                                                 int threads, std::optional<TanhWarp> warp = std::nullopt);

}  // namespace bgkmap
