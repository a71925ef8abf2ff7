// The registry of mapping methods: each is a folder under src/methods/ that defines
// <name>_descriptor() (docs/ADDING_A_METHOD.md), and one line below.
#include <algorithm>
#include <string>
#include <vector>

#include "bgkmap/methods/method_descriptor.hpp"

// Every method --method takes, one line each, in --help's order (the list ends at the comment).
#define BGKMAP_METHODS(METHOD) \
  METHOD(bgkl)                 \
  METHOD(bgk)                  \
  METHOD(counting)             \
  METHOD(octomap)              \
  METHOD(gpoctomap)            \
  METHOD(gpom)                 \
  METHOD(bhm)                  \
  METHOD(wgpom)                \
  /* end of the methods */

namespace bgkmap {

#define BGKMAP_DECLARE_METHOD(name) const MethodDescriptor& name##_descriptor();
BGKMAP_METHODS(BGKMAP_DECLARE_METHOD)
#undef BGKMAP_DECLARE_METHOD

const std::vector<const MethodDescriptor*>& method_descriptors() {
#define BGKMAP_LIST_METHOD(name) &name##_descriptor(),
  static const std::vector<const MethodDescriptor*> all = {BGKMAP_METHODS(BGKMAP_LIST_METHOD)};
#undef BGKMAP_LIST_METHOD
  return all;
}

bool MethodDescriptor::reads(const std::string& key) const {
  const std::string wanted = param_key(key);
  return std::any_of(params.begin(), params.end(), [&](const ParamSpec* p) { return p->key == wanted; });
}

const MethodDescriptor* find_method(const std::string& name) {
  for (const MethodDescriptor* method : method_descriptors())
    if (method->name == name) return method;
  return nullptr;
}

const std::vector<const ParamSpec*>& method_param_specs() {
  static const std::vector<const ParamSpec*> all = [] {
    std::vector<const ParamSpec*> out;
    for (const MethodDescriptor* method : method_descriptors())
      for (const ParamSpec* spec : method->params)
        if (std::find(out.begin(), out.end(), spec) == out.end()) out.push_back(spec);
    return out;
  }();
  return all;
}

const ParamSpec* find_method_param(const std::string& key) {
  const std::string wanted = param_key(key);
  for (const ParamSpec* spec : method_param_specs())
    if (spec->key == wanted) return spec;
  return nullptr;
}

std::vector<std::string> methods_reading(const std::string& key) {
  std::vector<std::string> out;
  for (const MethodDescriptor* method : method_descriptors())
    if (method->reads(key)) out.push_back(method->name);
  return out;
}

}  // namespace bgkmap
