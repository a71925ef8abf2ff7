// The GPOM and WGPOM methods (internal header; see gpom_method.cpp).
#pragma once

#include <memory>
#include <optional>

#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/methods/method.hpp"
#include "methods/wgpom/warped_gp.hpp"

namespace bgkmap {

// backend.threads <= 0: OpenMP's default (all cores). backend.backend: where the local models are
// solved (integrate/local_gp_batch.hpp: auto takes a GPU, opencl any device, cpu the CPU path).
std::unique_ptr<MappingMethod> make_gpom_method(const BuildParams& params, const MethodParams& method_params,
                                                const BackendOptions& backend);

// wgpom: gpom's local models with warped labels. `warp` given: that warp; else the warp is learned
// (method_params.wgp_terms tanh terms) when the map is first evaluated.
std::unique_ptr<MappingMethod> make_wgpom_method(const BuildParams& params, const MethodParams& method_params,
                                                 const BackendOptions& backend,
                                                 std::optional<TanhWarp> warp = std::nullopt);

}  // namespace bgkmap
