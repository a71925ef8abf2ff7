// A parameter's refusal as an error that each front end spells its own way, and its help text:
// made from the schema (param_spec.hpp) for the methods' parameters and the general ones alike.
#pragma once

#include <functional>
#include <stdexcept>
#include <string>

#include "bgkmap/methods/param_spec.hpp"

namespace bgkmap {

// A refusal of parameter values. Its pattern names each parameter by its key in braces ("{ds} 1e-30 m
// is below 0.01 of {resolution} 0.1 m"), so each front end names it as its user typed it: what()
// with the keys ("ds 1e-30 m ..."), as_flags() "--ds", as_keywords() "ds" / "prob_hit" (YAML, Python).
// Text from the user goes into a pattern through literal(), so its braces stay braces.
class ParamError : public std::invalid_argument {
 public:
  explicit ParamError(const std::string& pattern);
  static std::string literal(const std::string& text);
  std::string spelled(const std::function<std::string(const std::string& key)>& name) const;
  std::string as_flags() const;
  std::string as_keywords() const;

 private:
  std::string pattern_;
};

// ParamSpec::refusal()'s texts as errors (what() is the same text).
ParamError rejection(const ParamSpec& spec);
ParamError rejection(const ParamSpec& spec, const std::string& name);
// What a number is taken as ("in (0, 1000] m", "> 0 and finite, or 0: no limit"); empty for a choice.
std::string range_text(const ParamSpec& spec);
// --help's text: the help, then the unit and range ("Kernel length scale l (m); > 0 and finite").
std::string help_text(const ParamSpec& spec);

}  // namespace bgkmap
