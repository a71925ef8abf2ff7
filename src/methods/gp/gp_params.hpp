// The parameters every GP method reads (gpoctomap, gpom, wgpom), declared once.
#pragma once

#include "bgkmap/methods/param_spec.hpp"

namespace bgkmap {

// gp-noise: the observation noise sigma_n of K + sigma_n^2 I.
const ParamSpec& gp_noise_param();

}  // namespace bgkmap
