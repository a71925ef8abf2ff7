// --method bgkl: BGK-L, the Mapper itself. It reads no parameters of its own.
#include <memory>

#include "bgkmap/methods/method_descriptor.hpp"

namespace bgkmap {

const MethodDescriptor& bgkl_descriptor() {
  static const MethodDescriptor descriptor = [] {
    MethodDescriptor d;
    d.name = "bgkl";
    d.summary = "BGK-L, free beams as segments";
    d.capabilities.writes_bgk = true;
    d.capabilities.pose_uncertainty = true;
    d.capabilities.devices = {"cpu", "opencl"};
    d.variance = "the variance of the cell's Beta posterior (occupancy is its mean)";
    d.make = [](const BuildParams& p, const MethodParams&, const BackendOptions& b) {
      return make_bgkl_method(std::make_unique<Mapper>(p, make_integrator(b)));
    };
    return d;
  }();
  return descriptor;
}

}  // namespace bgkmap
