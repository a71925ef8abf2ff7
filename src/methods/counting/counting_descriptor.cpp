// --method counting: the counting sensor model. It reads forget-half-life (bgkl_descriptor.cpp).
#include "bgkmap/methods/method_descriptor.hpp"
#include "methods/bgkl/bgk_map_method.hpp"
#include "methods/counting/counting_method.hpp"

namespace bgkmap {

const MethodDescriptor& counting_descriptor() {
  static const MethodDescriptor descriptor = [] {
    MethodDescriptor d;
    d.name = "counting";
    d.summary = "counting sensor model";
    d.capabilities.writes_bgk = true;
    d.variance = "the variance of the cell's Beta posterior (occupancy is its mean)";
    d.params = {&forget_half_life_param()};
    d.make = [](const BuildParams& p, const MethodParams& m, const BackendOptions&) {
      return make_counting_method(p, m.number(forget_half_life_param().key));
    };
    return d;
  }();
  return descriptor;
}

}  // namespace bgkmap
