// What a mapping method is, as the registry (src/methods/registry.cpp) lists it: its name, a
// one-line summary, the parameters it reads, what it can do, what its variance means, and the
// factory that makes it. --method, --help, the flags, YAML keys and the report are made from these.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "bgkmap/core/params.hpp"
#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/methods/method.hpp"
#include "bgkmap/methods/method_params.hpp"
#include "bgkmap/methods/param_spec.hpp"

namespace bgkmap {

struct MethodCapabilities {
  bool writes_bgk = false;        // else only the formats check_output names (.ot/.bt, probability maps)
  bool maps_2d = true, maps_3d = true;
  bool pose_uncertainty = false;  // takes a scan's pose uncertainty (MappingMethod::uses_pose_uncertainty)
  std::vector<std::string> devices = {"cpu"};  // where --backend may run it: cpu, opencl
};

// `method_params` is valid (MethodParams::validate) and `params` too.
using MethodFactory = std::unique_ptr<MappingMethod> (*)(const BuildParams& params, const MethodParams& method_params,
                                                         const BackendOptions& backend);
// The rules between its parameters; throws std::invalid_argument. May be null.
using MethodCheck = void (*)(const MethodParams& method_params);

struct MethodDescriptor {
  std::string name;     // --method's value
  std::string summary;  // one line, in --method's help
  std::vector<const ParamSpec*> params;  // those it reads, in --help's order; shared ones are the same object
  MethodCapabilities capabilities;
  std::string variance;  // what CellEstimate::variance means for it
  MethodCheck check = nullptr;
  MethodFactory make = nullptr;

  bool reads(const std::string& key) const;
};

// Every method, in --help's order (method_names() is their names).
const std::vector<const MethodDescriptor*>& method_descriptors();
// The method called `name`, or null.
const MethodDescriptor* find_method(const std::string& name);
// Every method's parameters, each once, in the order the methods list them.
const std::vector<const ParamSpec*>& method_param_specs();
// The parameter of this key (dashes or underscores), or null.
const ParamSpec* find_method_param(const std::string& key);
// The methods that read a parameter, in method_descriptors()' order.
std::vector<std::string> methods_reading(const std::string& key);

}  // namespace bgkmap
