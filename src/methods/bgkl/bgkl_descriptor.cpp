// --method bgkl: BGK-L, the Mapper itself, and forget-half-life, which bgk and counting read too.
#include <memory>

#include "bgkmap/methods/method_descriptor.hpp"
#include "methods/bgkl/bgk_map_method.hpp"

namespace bgkmap {

const ParamSpec& forget_half_life_param() {
  static const ParamSpec spec =
      ParamSpec::number("forget-half-life", 0, above(0), at_most(1e9),
                        "Half-life of the evidence in scans: each scan moves every cell's alpha and beta "
                        "toward the prior by 2^(-1/H); 0 = off")
          .in_unit("scans")
          .with_zero_meaning("off");
  return spec;
}

const MethodDescriptor& bgkl_descriptor() {
  static const MethodDescriptor descriptor = [] {
    MethodDescriptor d;
    d.name = "bgkl";
    d.summary = "BGK-L, free beams as segments";
    d.params = {&forget_half_life_param()};
    d.capabilities.writes_bgk = true;
    d.capabilities.pose_uncertainty = true;
    d.capabilities.devices = {"cpu", "opencl"};
    d.variance = "the variance of the cell's Beta posterior (occupancy is its mean)";
    d.make = [](const BuildParams& p, const MethodParams& m, const BackendOptions& b) {
      auto mapper = std::make_unique<Mapper>(p, make_integrator(b));
      mapper->set_forget_half_life(m.number(forget_half_life_param().key));
      return make_bgkl_method(std::move(mapper));
    };
    return d;
  }();
  return descriptor;
}

}  // namespace bgkmap
