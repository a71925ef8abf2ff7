// The values of the parameters only some methods read, keyed by the schema (param_spec.hpp): every
// parameter of every registered method, at its default until set. Each method reads its own typed
// struct from it (methods/<name>/), so a new method adds no field here.
#pragma once

#include <map>
#include <string>

#include "bgkmap/methods/param_spec.hpp"

namespace bgkmap {

class MethodParams {
 public:
  // Every registered method's parameters at their defaults.
  MethodParams();

  // Sets a number or whole number, or a choice by name. Keys with dashes or underscores. Throws
  // std::invalid_argument with a one-line reason for an unknown key, a value of another kind, or
  // one out of range (ParamSpec::refusal). A choice with presets (ParamSpec::presets) also sets
  // the values its name gives every parameter not set explicitly, before or after it.
  void set(const std::string& key, double value);
  void set(const std::string& key, int value) { set(key, static_cast<double>(value)); }  // set("wgp-terms", 0)
  void set(const std::string& key, const std::string& name);
  void set(const std::string& key, const char* name) { set(key, std::string(name)); }

  // The value of a number or whole number; of a whole number as an int; of a choice. Throw
  // std::invalid_argument for an unknown key or another kind.
  double number(const std::string& key) const;
  int whole(const std::string& key) const;
  const std::string& choice(const std::string& key) const;

  // The rules between parameters (clamp-min < clamp-max, ...) of every registered method; throws
  // std::invalid_argument with a one-line reason. Each value alone is checked by set().
  void validate() const;

 private:
  struct Value {
    const ParamSpec* spec = nullptr;
    double number = 0;
    std::string name;
    bool given = false;  // set explicitly: no preset changes it
  };
  void apply_presets(const ParamSpec& spec, const std::string& name);
  const Value& at(const std::string& key, ParamKind kind) const;
  Value& at(const std::string& key, ParamKind kind);

  std::map<std::string, Value> values_;  // by key (dashes)
};

}  // namespace bgkmap
