#include "bgkmap/tune/tunable.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>

#include "bgkmap/methods/method_descriptor.hpp"
#include "core/float_decimal.hpp"

namespace bgkmap::tune {

namespace {

// A method parameter tune searches, by its schema key (method_descriptor.hpp): its name is the
// schema's keyword and its values go through MethodParams::set, so a search range that left the
// schema's would be refused there (the tests check every one lies within it).
TunableParam method_param(const std::string& key, double lo, double hi, RangeUnit unit, bool log_scale) {
  const ParamSpec* spec = find_method_param(key);
  if (!spec) throw std::logic_error("tune: no method parameter '" + key + "'");
  TunableParam t;
  t.name = spec->keyword();
  t.lo = lo;
  t.hi = hi;
  t.unit = unit;
  t.log_scale = log_scale;
  t.get = [key](const BuildParams&, const MethodParams& m) { return m.number(key); };
  t.set = [key](BuildParams&, MethodParams& m, double v) { m.set(key, v); };
  return t;
}

// The kernel's length l, rebuilt for each value.
TunableParam ell_param() {
  return {"ell", 1.0, 10.0, RangeUnit::kCells, true, false,
          [](const BuildParams& p, const MethodParams&) { return as_decimal(p.kernel.ell_m); },
          [](BuildParams& p, MethodParams&, double v) { p.kernel.ell_m = static_cast<float>(v); }};
}

// A Beta posterior's prior alpha0 and beta0: chosen from one build's sums (prior_sums.hpp), as
// every Beta method's counts are the prior plus what the scans added.
std::vector<TunableParam> prior_params(RangeUnit unit) {
  return {{"prior_alpha", 1e-6, 10.0, unit, true, true,
           [](const BuildParams& p, const MethodParams&) { return as_decimal(p.prior.alpha0); },
           [](BuildParams& p, MethodParams&, double v) { p.prior.alpha0 = static_cast<float>(v); }},
          {"prior_beta", 1e-6, 10.0, unit, true, true,
           [](const BuildParams& p, const MethodParams&) { return as_decimal(p.prior.beta0); },
           [](BuildParams& p, MethodParams&, double v) { p.prior.beta0 = static_cast<float>(v); }}};
}

std::vector<TunableParam> joined(std::vector<TunableParam> a, const std::vector<TunableParam>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

std::vector<TunableParam> gp_params() {
  return {method_param("gp-length", 2.0, 20.0, RangeUnit::kCells, true),
          method_param("gp-signal", 0.1, 10.0, RangeUnit::kAbsolute, true),
          method_param("gp-noise", 0.01, 1.0, RangeUnit::kAbsolute, true)};
}

const std::map<std::string, std::vector<TunableParam>>& tables() {
  static const std::map<std::string, std::vector<TunableParam>> t = {
      {"bgkl", joined({ell_param()}, prior_params(RangeUnit::kSigma0))},
      // BGKOctoMap's counts are sigma0 times its kernel sums too; counting adds 1 per hit or miss.
      {"bgk", joined({ell_param(), method_param("free-resolution", 0.5, 5.0, RangeUnit::kCells, true)},
                     prior_params(RangeUnit::kSigma0))},
      {"counting", prior_params(RangeUnit::kAbsolute)},
      {"octomap",
       {method_param("prob-hit", 0.51, 0.99, RangeUnit::kAbsolute, false),
        method_param("prob-miss", 0.01, 0.49, RangeUnit::kAbsolute, false),
        method_param("clamp-min", 0.001, 0.49, RangeUnit::kAbsolute, true),
        method_param("clamp-max", 0.51, 0.999, RangeUnit::kAbsolute, false)}},
      {"gpoctomap",
       {ell_param(), method_param("gp-noise", 0.01, 1.0, RangeUnit::kAbsolute, true),
        method_param("gp-squash", 0.01, 10.0, RangeUnit::kAbsolute, true)}},
      {"gpom", gp_params()},
      {"wgpom", gp_params()},
      {"bhm",
       {method_param("bhm-gamma", 0.02, 2.0, RangeUnit::kPerCellSquared, true),
        method_param("bhm-spacing", 1.5, 10.0, RangeUnit::kCells, true)}},
  };
  return t;
}

}  // namespace

const std::vector<std::string>& tunable_methods() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> out;  // in --method's order
    for (const std::string& name : method_names())
      if (tables().count(name)) out.push_back(name);
    return out;
  }();
  return names;
}

const std::vector<TunableParam>& tunable_params(const std::string& method) {
  const auto it = tables().find(method);
  if (it == tables().end()) {
    std::string list;
    for (const std::string& name : tunable_methods()) list += (list.empty() ? "" : ", ") + name;
    throw std::invalid_argument("tune chooses the parameters of " + list + ", not of '" + method + "'");
  }
  return it->second;
}

Range absolute_range(const TunableParam& param, const BuildParams& params) {
  const double r = params.grid.resolution_m;
  switch (param.unit) {
    case RangeUnit::kCells: return {param.lo * r, param.hi * r};
    case RangeUnit::kPerCellSquared: return {param.lo / (r * r), param.hi / (r * r)};
    case RangeUnit::kSigma0: return {param.lo * params.kernel.sigma0, param.hi * params.kernel.sigma0};
    case RangeUnit::kAbsolute: break;
  }
  return {param.lo, param.hi};
}

double to_unit(bool log_scale, const Range& range, double value) {
  const double v = std::clamp(value, range.lo, range.hi);
  const double u = log_scale ? std::log(v / range.lo) / std::log(range.hi / range.lo)
                                   : (v - range.lo) / (range.hi - range.lo);
  return std::clamp(u, 0.0, 1.0);
}

double from_unit(bool log_scale, const Range& range, double unit) {
  const double u = std::clamp(unit, 0.0, 1.0);
  const double v = log_scale ? range.lo * std::pow(range.hi / range.lo, u) : range.lo + (range.hi - range.lo) * u;
  return std::clamp(v, range.lo, range.hi);
}

}  // namespace bgkmap::tune
