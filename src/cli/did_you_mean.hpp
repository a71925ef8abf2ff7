// A usage error that names something the command does not have (a mistyped subcommand or flag),
// explained with the closest name it does have.
#pragma once

#include <CLI/CLI.hpp>

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace bgkmap::cli {

// Edits (insertions, deletions, substitutions, swaps of neighbours) that turn `a` into `b`.
size_t edit_distance(const std::string& a, const std::string& b);

// The name of `known` that `typed` most likely meant (underscores read as dashes: the config's
// spelling of a flag), or "" when none is close.
std::string closest_name(const std::string& typed, const std::vector<std::string>& known);

// After a failed parse of `app`: "unknown subcommand 'biuld'; did you mean 'build'?" or "build:
// unknown flag '--max_range'; did you mean '--max-range'?"; nullopt when every name was known.
std::optional<std::string> unknown_name_error(const CLI::App& app);

}  // namespace bgkmap::cli
