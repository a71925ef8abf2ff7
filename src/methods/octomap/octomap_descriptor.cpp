// --method octomap: liboctomap's OcTree, and the parameters of its sensor model.
#include <stdexcept>

#include "bgkmap/methods/method_descriptor.hpp"
#include "methods/octomap/octomap_method.hpp"

namespace bgkmap {

namespace {

// OctoMap's own defaults.
const ParamSpec& prob_hit() {
  static const ParamSpec s =
      ParamSpec::number("prob-hit", 0.7, above(0.5), below(1), "Hit probability of the sensor model");
  return s;
}
const ParamSpec& prob_miss() {
  static const ParamSpec s =
      ParamSpec::number("prob-miss", 0.4, above(0), below(0.5), "Miss probability of the sensor model");
  return s;
}
const ParamSpec& clamp_min() {
  static const ParamSpec s = ParamSpec::number("clamp-min", 0.1192, above(0), below(1), "Lower clamping probability");
  return s;
}
const ParamSpec& clamp_max() {
  static const ParamSpec s = ParamSpec::number("clamp-max", 0.971, above(0), below(1), "Upper clamping probability");
  return s;
}

void check(const MethodParams& m) {
  if (!(m.number("clamp-min") < m.number("clamp-max")))
    throw std::invalid_argument("clamp-min and clamp-max must satisfy 0 < clamp-min < clamp-max < 1");
}

}  // namespace

OctomapParams octomap_params(const MethodParams& m) {
  return {m.number("prob-hit"), m.number("prob-miss"), m.number("clamp-min"), m.number("clamp-max")};
}

const MethodDescriptor& octomap_descriptor() {
  static const MethodDescriptor descriptor = [] {
    MethodDescriptor d;
    d.name = "octomap";
    d.summary = "liboctomap's OcTree and sensor model";
    d.params = {&prob_hit(), &prob_miss(), &clamp_min(), &clamp_max()};
    d.variance = "none: a log-odds cell carries no variance";
    d.check = check;
    d.make = [](const BuildParams& p, const MethodParams& m, const BackendOptions&) { return make_octomap_method(p, m); };
    return d;
  }();
  return descriptor;
}

}  // namespace bgkmap
