// The GPOctoMap baseline (internal header; see gpoctomap_method.cpp).
#pragma once

#include <memory>

#include "bgkmap/methods/method.hpp"

namespace bgkmap {

// The parameters gpoctomap reads (gpoctomap_descriptor.cpp); its kernel's l and scale are --ell and --sigma0.
struct GpOctomapParams {
  double free_resolution_m = 0;
  double gp_noise = 0, gp_squash = 0;
};
GpOctomapParams gpoctomap_params(const MethodParams& method_params);

// threads <= 0: OpenMP's default (all cores).
std::unique_ptr<MappingMethod> make_gpoctomap_method(const BuildParams& params, const MethodParams& method_params,
                                                     int threads);

}  // namespace bgkmap
