// --method wgpom: gpom with a learned monotonic warp of the labels; gpom's parameters and wgp-terms.
#include "bgkmap/methods/method_descriptor.hpp"
#include "methods/gpom/gpom_method.hpp"

namespace bgkmap {

namespace {
const ParamSpec& wgp_terms() {
  static const ParamSpec s = ParamSpec::whole_number(
      "wgp-terms", 3, 0, 10,
      "Tanh terms of the warp of the labels, learned by maximising the warped marginal likelihood (0: no warp, "
      "gpom's map)");
  return s;
}
}  // namespace

const MethodDescriptor& wgpom_descriptor() {
  static const MethodDescriptor descriptor = [] {
    MethodDescriptor d;
    d.name = "wgpom";
    d.summary = "warped GPOM: gpom with a learned monotonic warp of the labels";
    d.params = gpom_param_specs();
    d.params.push_back(&wgp_terms());
    d.capabilities.pose_uncertainty = true;
    d.capabilities.devices = {"cpu", "opencl"};
    d.variance = "the variance of the local model's prediction in label space (the inverse warp's mean and variance)";
    d.make = [](const BuildParams& p, const MethodParams& m, const BackendOptions& b) {
      return make_wgpom_method(p, m, b);
    };
    return d;
  }();
  return descriptor;
}

}  // namespace bgkmap
