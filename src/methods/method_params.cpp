// The store of method parameter values, checked against the schema as they are set.
#include "bgkmap/methods/method_params.hpp"

#include <stdexcept>
#include <string>

#include "bgkmap/methods/method_descriptor.hpp"
#include "bgkmap/methods/param_error.hpp"

namespace bgkmap {

MethodParams::MethodParams() {
  for (const ParamSpec* spec : method_param_specs()) values_[spec->key] = {spec, spec->default_number, spec->default_choice};
}

const MethodParams::Value& MethodParams::at(const std::string& key, ParamKind kind) const {
  const auto it = values_.find(param_key(key));
  if (it == values_.end()) throw std::invalid_argument("unknown method parameter '" + key + "'");
  const ParamSpec& spec = *it->second.spec;
  const bool named = spec.kind == ParamKind::kChoice;
  if (named != (kind == ParamKind::kChoice))
    throw std::invalid_argument(spec.key + (named ? " takes a name, not a number" : " takes a number, not a name"));
  if (kind == ParamKind::kWholeNumber && spec.kind != ParamKind::kWholeNumber)
    throw std::invalid_argument(spec.key + " is not a whole number parameter");
  return it->second;
}

MethodParams::Value& MethodParams::at(const std::string& key, ParamKind kind) {
  return const_cast<Value&>(static_cast<const MethodParams&>(*this).at(key, kind));
}

void MethodParams::set(const std::string& key, double value) {
  Value& v = at(key, ParamKind::kNumber);
  if (!v.spec->accepts(value)) throw rejection(*v.spec);
  v.number = value;
  v.given = true;
}

void MethodParams::set(const std::string& key, const std::string& name) {
  Value& v = at(key, ParamKind::kChoice);
  if (!v.spec->accepts(name)) throw rejection(*v.spec, name);
  v.name = name;
  v.given = true;
  apply_presets(*v.spec, name);
}

void MethodParams::apply_presets(const ParamSpec& spec, const std::string& name) {
  // Every preset's parameters back to their defaults, then the chosen name's values.
  for (int pass = 0; pass < 2; ++pass)
    for (const auto& [choice, preset] : spec.presets) {
      if (pass == 1 && choice != name) continue;
      for (const PresetValue& p : preset) {
        Value& v = values_.at(param_key(p.key));
        if (v.given) continue;
        v.number = pass == 1 ? p.number : v.spec->default_number;
        v.name = pass == 1 ? p.name : v.spec->default_choice;
      }
    }
}

double MethodParams::number(const std::string& key) const { return at(key, ParamKind::kNumber).number; }

int MethodParams::whole(const std::string& key) const { return static_cast<int>(at(key, ParamKind::kWholeNumber).number); }

const std::string& MethodParams::choice(const std::string& key) const { return at(key, ParamKind::kChoice).name; }

void MethodParams::validate() const {
  for (const MethodDescriptor* method : method_descriptors())
    if (method->check) method->check(*this);
}

}  // namespace bgkmap
