// BuildParams <-> JSON, with the same names as the CLI flags (dashes as underscores). Used by the
// report's "params", the native map header and `bgkmap info`.
#pragma once

#include <nlohmann/json.hpp>

#include "bgkmap/core/params.hpp"

namespace bgkmap {

nlohmann::json params_to_json(const BuildParams& params);
// Reads every key params_to_json writes; missing keys keep their defaults, unknown keys and wrong
// types throw std::invalid_argument naming the key.
BuildParams params_from_json(const nlohmann::json& json);

}  // namespace bgkmap
