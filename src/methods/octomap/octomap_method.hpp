// The OctoMap baseline: liboctomap's OcTree and its own sensor model, fed by the shared readers
// and preprocessing (NaN/Inf dropped, downsampling, viewpoint). Internal header.
#pragma once

#include <memory>

#include "bgkmap/methods/method.hpp"

namespace bgkmap {

std::unique_ptr<MappingMethod> make_octomap_method(const BuildParams& params, const MethodParams& method_params);

}  // namespace bgkmap
