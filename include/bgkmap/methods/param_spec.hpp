// A parameter only some methods read, as one schema: its key, kind, range, default and help. The
// flags of `bgkmap build`, the YAML config's keys, the report's method_params, Python's keywords,
// --help and the checks of a value are all made from it (docs/ADDING_A_METHOD.md).
#pragma once

#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace bgkmap {

enum class ParamKind {
  kNumber,       // a finite number within the range
  kWholeNumber,  // a count: a whole number within the range (an INT flag, an integer in the report)
  kChoice,       // one name of `choices`
};

// One end of a range: closed takes the value itself ("[", "]"), open does not ("(", ")"). An
// infinite end is open: the value must then be finite.
struct RangeEnd {
  double value = 0;
  bool closed = false;
};
inline RangeEnd above(double v) { return {v, false}; }
inline RangeEnd at_least(double v) { return {v, true}; }
inline RangeEnd below(double v) { return {v, false}; }
inline RangeEnd at_most(double v) { return {v, true}; }
inline RangeEnd unbounded() { return {std::numeric_limits<double>::infinity(), false}; }

// What one name of a choice sets: another parameter's value (a number, or a name for a choice).
struct PresetValue {
  std::string key;
  double number = 0;
  std::string name;
};

struct ParamSpec {
  // The flag's spelling ("gp-noise"); YAML takes it with dashes or underscores, the report and
  // Python's keywords with underscores (keyword()).
  std::string key;
  ParamKind kind = ParamKind::kNumber;
  RangeEnd lo = above(-std::numeric_limits<double>::infinity()), hi = unbounded();
  std::string unit;        // of the value ("m", "rad"): printed after a bounded range
  std::string zero_means;  // not empty: 0 is taken too, outside the range, and means this
  std::string note;        // what the range stands for, in the refusal's parentheses
  double default_number = 0;
  std::vector<std::string> choices;  // kChoice: the one table of its names; the default is default_choice
  std::string default_choice;
  std::string help;
  // kChoice: per name, the values it gives other parameters not set explicitly (MethodParams::set).
  std::vector<std::pair<std::string, std::vector<PresetValue>>> presets;

  static ParamSpec number(std::string key, double default_value, RangeEnd lo, RangeEnd hi, std::string help) {
    ParamSpec s;
    s.key = std::move(key);
    s.kind = ParamKind::kNumber;
    s.default_number = default_value;
    s.lo = lo;
    s.hi = hi;
    s.help = std::move(help);
    return s;
  }
  static ParamSpec whole_number(std::string key, double default_value, double lo, double hi, std::string help) {
    ParamSpec s = number(std::move(key), default_value, at_least(lo), at_most(hi), std::move(help));
    s.kind = ParamKind::kWholeNumber;
    return s;
  }
  static ParamSpec choice(std::string key, std::vector<std::string> names, std::string default_name,
                          std::string help) {
    ParamSpec s;
    s.key = std::move(key);
    s.kind = ParamKind::kChoice;
    s.choices = std::move(names);
    s.default_choice = std::move(default_name);
    s.help = std::move(help);
    return s;
  }
  ParamSpec& in_unit(std::string u) {
    unit = std::move(u);
    return *this;
  }
  ParamSpec& with_zero_meaning(std::string meaning) {
    zero_means = std::move(meaning);
    return *this;
  }
  ParamSpec& with_preset(std::string name, std::vector<PresetValue> values) {
    presets.emplace_back(std::move(name), std::move(values));
    return *this;
  }
  ParamSpec& with_note(std::string text) {
    note = std::move(text);
    return *this;
  }

  // The key with underscores: the report's and Python's spelling (gp_noise).
  std::string keyword() const;
  // Whether a number (of kNumber or kWholeNumber) is taken.
  bool accepts(double value) const;
  // Whether a name is one of the choices.
  bool accepts(const std::string& name) const;
  // The one-line refusal of a value not taken: "gp-noise must be in (0, 1000] (...)",
  // "gp-covariance must be matern, sparse, se or nn, not 'x'".
  std::string refusal() const;
  std::string refusal(const std::string& name) const;
};

// A key with underscores as dashes (the flag's spelling): YAML's gp_noise is gp-noise.
std::string param_key(std::string key);

}  // namespace bgkmap
