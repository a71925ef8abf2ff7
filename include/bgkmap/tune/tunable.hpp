// The parameters `bgkmap tune` chooses for each method, each with the range it searches and
// whether it searches on a log scale. Lengths are given in cells (times the resolution), BHM's
// gamma in 1 / cells^2, BGK-L's prior in units of sigma0, so one table fits every grid.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "bgkmap/core/params.hpp"
#include "bgkmap/methods/method.hpp"

namespace bgkmap::tune {

enum class RangeUnit { kAbsolute, kCells, kPerCellSquared, kSigma0 };

struct TunableParam {
  std::string name;  // the config key (the flag with dashes as underscores)
  double lo = 0, hi = 0;  // the range, in `unit`
  RangeUnit unit = RangeUnit::kAbsolute;
  bool log_scale = false;
  // BGK-L's prior: chosen from one build's kernel sums (prior_sums.hpp), not by rebuilding.
  bool from_sums = false;
  std::function<double(const BuildParams&, const MethodParams&)> get;
  std::function<void(BuildParams&, MethodParams&, double)> set;
};

// The methods tune accepts (those with a table here), in method_names()'s order.
const std::vector<std::string>& tunable_methods();

// The table of `method`; throws std::invalid_argument naming tunable_methods() for any other.
const std::vector<TunableParam>& tunable_params(const std::string& method);

// The range in the parameter's own unit (metres, 1/m^2, ...) for these build parameters.
struct Range {
  double lo = 0, hi = 0;
};
Range absolute_range(const TunableParam& param, const BuildParams& params);

// The search coordinate in [0, 1] of a value and back (log or linear across the range); values
// outside the range are clamped to it.
double to_unit(bool log_scale, const Range& range, double value);
double from_unit(bool log_scale, const Range& range, double unit);

}  // namespace bgkmap::tune
