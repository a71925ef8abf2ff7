// --method gpoctomap: GP regression per block fused by a Bayesian committee machine.
#include "bgkmap/methods/method_descriptor.hpp"
#include "methods/bgk/bgk_method.hpp"
#include "methods/gp/gp_params.hpp"
#include "methods/gpoctomap/gpoctomap_method.hpp"

namespace bgkmap {

namespace {
const ParamSpec& gp_squash() {
  static const ParamSpec s = ParamSpec::number("gp-squash", 0.1, above(0), unbounded(),
                                               "Slope of the logistic squashing of the variance-weighted mean");
  return s;
}
}  // namespace

GpOctomapParams gpoctomap_params(const MethodParams& m) {
  return {m.number("free-resolution"), m.number("gp-noise"), m.number("gp-squash")};
}

const MethodDescriptor& gpoctomap_descriptor() {
  static const MethodDescriptor descriptor = [] {
    MethodDescriptor d;
    d.name = "gpoctomap";
    d.summary = "GP regression per block fused by a Bayesian committee machine";
    d.params = {&free_resolution_param(), &gp_noise_param(), &gp_squash()};
    d.variance = "the variance of the BCM-fused GP prediction of the latent label (+1 occupied, -1 free); occupancy "
                 "is the logistic squashing of mean / variance";
    d.make = [](const BuildParams& p, const MethodParams& m, const BackendOptions& b) {
      p.check_kernel_reach();
      return make_gpoctomap_method(p, m, b.threads);
    };
    return d;
  }();
  return descriptor;
}

}  // namespace bgkmap
