// The YAML of parameters `bgkmap tune` writes: every build parameter and the method's own ones,
// under the keys `build --config` and `eval --config` read, so the file alone reproduces the map.
#pragma once

#include <string>
#include <vector>

#include "bgkmap/core/params.hpp"
#include "bgkmap/methods/method.hpp"

namespace bgkmap::cli {

// `comments` become leading "# " lines. The same arguments always give the same bytes.
std::string tuned_config_yaml(const std::string& method, const BuildParams& params, const MethodParams& method_params,
                              const std::vector<std::string>& comments);

}  // namespace bgkmap::cli
