// A method parameter's checks and refusals, made from its schema alone.
#include "bgkmap/methods/param_spec.hpp"

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
std::string range_text(const ParamSpec& s) {
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

std::string ParamSpec::refusal() const {
  if (kind == ParamKind::kChoice) return key + " must be " + listed(choices) + ", not a number";
  return key + " must be " + range_text(*this);
}

std::string ParamSpec::refusal(const std::string& name) const {
  if (kind != ParamKind::kChoice) return key + " must be a number (" + range_text(*this) + "), not '" + name + "'";
  return key + " must be " + listed(choices) + ", not '" + name + "'";
}

}  // namespace bgkmap
