// --method bgk: BGKOctoMap, and free-resolution, which gpoctomap and bhm read too.
#include "bgkmap/methods/method_descriptor.hpp"
#include "methods/bgk/bgk_method.hpp"
#include "methods/bgkl/bgk_map_method.hpp"

namespace bgkmap {

const ParamSpec& free_resolution_param() {
  static const ParamSpec spec = ParamSpec::number("free-resolution", 0.1, above(0), unbounded(),
                                                  "Spacing of the free points sampled along each beam (m)")
                                    .in_unit("m");
  return spec;
}

const MethodDescriptor& bgk_descriptor() {
  static const MethodDescriptor descriptor = [] {
    MethodDescriptor d;
    d.name = "bgk";
    d.summary = "BGKOctoMap: free points sampled along beams";
    d.params = {&free_resolution_param(), &forget_half_life_param()};
    d.capabilities.writes_bgk = true;
    d.capabilities.pose_uncertainty = true;
    d.capabilities.devices = {"cpu", "opencl"};
    d.variance = "the variance of the cell's Beta posterior (occupancy is its mean)";
    d.make = [](const BuildParams& p, const MethodParams& m, const BackendOptions& b) {
      return make_bgk_method(p, m, make_integrator(b));
    };
    return d;
  }();
  return descriptor;
}

}  // namespace bgkmap
