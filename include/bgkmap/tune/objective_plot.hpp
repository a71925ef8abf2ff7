// A picture of a tune run: the objective of every trial against each parameter's value (one panel
// per parameter, on its search scale), with the given and the chosen values marked.
#pragma once

#include <filesystem>

#include "bgkmap/tune/tune.hpp"

namespace bgkmap::tune {

// Written atomically as PNG. Failed trials are left out.
void write_objective_plot(const std::filesystem::path& file, const std::string& method, const TuneResult& result,
                          Objective objective);

}  // namespace bgkmap::tune
