// --ot-values, the option of the commands that write maps (build, merge): what a .ot output holds.
#pragma once

#include <CLI/CLI.hpp>

#include <string>

namespace bgkmap::cli {

inline void add_ot_values_option(CLI::App& cmd, std::string& ot_values) {
  cmd.add_option("--ot-values", ot_values,
                 "What a .ot holds: classified (the cells the map calls occupied or free, as OctoMap's tools read "
                 "them: unknown cells are left out) or mean (every cell's probability, for bgkmap eval; OctoMap's "
                 "tools then call every cell above 0.5 occupied)")
      ->check(CLI::IsMember({"classified", "mean"}))
      ->capture_default_str();
}

}  // namespace bgkmap::cli
