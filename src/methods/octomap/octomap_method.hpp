// The OctoMap baseline: liboctomap's OcTree and its own sensor model, fed by the shared readers
// and preprocessing (NaN/Inf dropped, downsampling, viewpoint). Internal header.
#pragma once

#include <memory>

#include "bgkmap/methods/method.hpp"

namespace bgkmap {

// The parameters octomap reads (octomap_descriptor.cpp): OctoMap's sensor model.
struct OctomapParams {
  double prob_hit = 0, prob_miss = 0, clamp_min = 0, clamp_max = 0;
};
OctomapParams octomap_params(const MethodParams& method_params);

std::unique_ptr<MappingMethod> make_octomap_method(const BuildParams& params, const MethodParams& method_params);

}  // namespace bgkmap
