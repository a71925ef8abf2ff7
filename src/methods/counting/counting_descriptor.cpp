// --method counting: the counting sensor model. It reads no parameters of its own.
#include "bgkmap/methods/method_descriptor.hpp"
#include "methods/counting/counting_method.hpp"

namespace bgkmap {

const MethodDescriptor& counting_descriptor() {
  static const MethodDescriptor descriptor = [] {
    MethodDescriptor d;
    d.name = "counting";
    d.summary = "counting sensor model";
    d.capabilities.writes_bgk = true;
    d.variance = "the variance of the cell's Beta posterior (occupancy is its mean)";
    d.make = [](const BuildParams& p, const MethodParams&, const BackendOptions&) { return make_counting_method(p); };
    return d;
  }();
  return descriptor;
}

}  // namespace bgkmap
