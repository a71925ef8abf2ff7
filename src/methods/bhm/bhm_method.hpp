// The Bayesian Hilbert map method (internal header; see bhm_method.cpp).
#pragma once

#include <memory>
#include <string>

#include "bgkmap/methods/method.hpp"

namespace bgkmap {

// The parameters bhm reads (bhm_descriptor.cpp). Free space as "points" sampled every
// free_resolution_m along each beam, or as "beams": each beam's exact line integral (2-D).
struct BhmMethodParams {
  double free_resolution_m = 0;
  double bhm_spacing = 0, bhm_gamma = 0, bhm_support_var = 0, bhm_prior_var = 0;
  int bhm_evidence_scans = 0;
  double bhm_support_side = 0;
  int bhm_em_iterations = 0, bhm_block_side = 0;
  std::string bhm_free;
  bool bhm_bias = false;
};
BhmMethodParams bhm_method_params(const MethodParams& method_params);

// backend: where each block's Phi^T Lambda Phi is summed (cpu, opencl, auto: integrate/block_gram.hpp);
// its threads <= 0: OpenMP's default (all cores).
std::unique_ptr<MappingMethod> make_bhm_method(const BuildParams& params, const MethodParams& method_params,
                                               const BackendOptions& backend);

}  // namespace bgkmap
