// A parameter's checks, refusals and help, made from its schema alone.
#include "bgkmap/methods/param_spec.hpp"
#include "bgkmap/methods/param_error.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/number_text.hpp"

namespace bgkmap {

namespace {

std::string with(std::string text, char from, char to) {
  std::replace(text.begin(), text.end(), from, to);
  return text;
}

// "a, b or c"
std::string listed(const std::vector<std::string>& names) {
  std::string out;
  for (size_t i = 0; i < names.size(); ++i) out += (i == 0 ? "" : i + 1 == names.size() ? " or " : ", ") + names[i];
  return out;
}

std::string interval(const RangeEnd& lo, const RangeEnd& hi) {
  return (lo.closed ? "[" : "(") + number_text(lo.value) + ", " + number_text(hi.value) + (hi.closed ? "]" : ")");
}

// What a taken number is: "in (0, 1000]", "> 0 and finite", "a whole number in [1, 100]".
std::string range_of(const ParamSpec& s) {
  const bool has_lo = std::isfinite(s.lo.value), has_hi = std::isfinite(s.hi.value);
  std::string text;
  if (s.kind == ParamKind::kWholeNumber) text = "a whole number in " + interval(s.lo, s.hi);
  else if (has_lo && has_hi) text = "in " + interval(s.lo, s.hi) + (s.unit.empty() ? "" : " " + s.unit);
  else if (has_lo) text = (s.lo.closed ? ">= " : "> ") + number_text(s.lo.value) + " and finite";
  else if (has_hi) text = (s.hi.closed ? "<= " : "< ") + number_text(s.hi.value) + " and finite";
  else text = "finite";
  if (!s.zero_means.empty()) text += ", or 0: " + s.zero_means;
  if (!s.note.empty()) text += " (" + s.note + ")";
  return text;
}

}  // namespace

std::string param_key(std::string key) { return with(std::move(key), '_', '-'); }

std::string ParamSpec::keyword() const { return with(key, '-', '_'); }

bool ParamSpec::accepts(double value) const {
  if (kind == ParamKind::kChoice) return false;
  if (!zero_means.empty() && value == 0) return true;
  // Every comparison is false for NaN; an infinite end is open, so infinities are refused too.
  const bool above_lo = lo.closed ? value >= lo.value : value > lo.value;
  const bool below_hi = hi.closed ? value <= hi.value : value < hi.value;
  if (!(above_lo && below_hi && std::isfinite(value))) return false;
  return kind != ParamKind::kWholeNumber || value == std::floor(value);
}

bool ParamSpec::accepts(const std::string& name) const {
  return kind == ParamKind::kChoice && std::find(choices.begin(), choices.end(), name) != choices.end();
}

namespace {
// The pattern with each {key} replaced by name(key), and {{ by {.
std::string spell(const std::string& pattern, const std::function<std::string(const std::string& key)>& name) {
  std::string out;
  size_t at = 0;
  for (size_t open; (open = pattern.find('{', at)) != std::string::npos;) {
    if (pattern.compare(open, 2, "{{") == 0) {
      out += pattern.substr(at, open + 1 - at);
      at = open + 2;
      continue;
    }
    const size_t close = pattern.find('}', open);
    if (close == std::string::npos) break;
    out += pattern.substr(at, open - at) + name(pattern.substr(open + 1, close - open - 1));
    at = close + 1;
  }
  return out + pattern.substr(at);
}
}  // namespace

ParamError::ParamError(const std::string& pattern)
    : std::invalid_argument(spell(pattern, [](const std::string& k) { return k; })), pattern_(pattern) {}

std::string ParamError::spelled(const std::function<std::string(const std::string& key)>& name) const {
  return spell(pattern_, name);
}

std::string ParamError::literal(const std::string& text) {
  std::string out;
  for (char c : text) out += c == '{' ? std::string("{{") : std::string(1, c);
  return out;
}

std::string ParamError::as_flags() const {
  return spelled([](const std::string& k) { return "--" + k; });
}

std::string ParamError::as_keywords() const {
  return spelled([](const std::string& k) { return with(k, '-', '_'); });
}

ParamError rejection(const ParamSpec& spec) {
  const std::string& key = spec.key;
  const std::vector<std::string>& choices = spec.choices;
  if (spec.kind == ParamKind::kChoice) return ParamError("{" + key + "} must be " + listed(choices) + ", not a number");
  return ParamError("{" + key + "} must be " + range_of(spec));
}

ParamError rejection(const ParamSpec& spec, const std::string& given) {
  const std::string& key = spec.key;
  const std::string name = ParamError::literal(given);
  const std::vector<std::string>& choices = spec.choices;
  if (spec.kind != ParamKind::kChoice) return ParamError("{" + key + "} must be a number (" + range_of(spec) + "), not '" + name + "'");
  return ParamError("{" + key + "} must be " + listed(choices) + ", not '" + name + "'");
}

std::string ParamSpec::refusal() const { return rejection(*this).what(); }

std::string ParamSpec::refusal(const std::string& name) const { return rejection(*this, name).what(); }

std::string range_text(const ParamSpec& spec) { return spec.kind == ParamKind::kChoice ? std::string() : range_of(spec); }

std::string help_text(const ParamSpec& spec) {
  if (spec.kind == ParamKind::kChoice) return spec.help;
  const bool bounded = std::isfinite(spec.lo.value) && std::isfinite(spec.hi.value);
  return spec.help + (spec.unit.empty() || bounded ? "" : " (" + spec.unit + ")") + "; " + range_text(spec);
}

}  // namespace bgkmap
