// The GPOM and WGPOM methods (internal header; see gpom_method.cpp).
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/methods/method.hpp"
#include "methods/wgpom/warped_gp.hpp"

namespace bgkmap {

// The parameters gpom and wgpom read (gpom_descriptor.cpp; wgpom adds wgp_terms).
struct GpomParams {
  double gp_noise = 0;
  std::string gp_covariance;  // matern, sparse, se or nn
  double gp_length_m = 0, gp_signal_var = 0;
  int gp_neighbours = 0;
  std::string gp_hyperparameters;  // given or learn
  double gp_range_sigma = 0, gp_bearing_sigma = 0;
  std::string gp_input_correlation;  // independent, scan or trajectory
  int wgp_terms = 0;
  std::string gp_mode;  // default or paper (gpom only)
  int gp_train_scans = 0, gp_train_points = 0;
};
GpomParams gpom_params(const MethodParams& method_params);
// gpom's parameters, which wgpom reads too.
const std::vector<const ParamSpec*>& gpom_param_specs();

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
