// OctoMap trees as ScoredMaps (internal; see bgkmap/eval/scored_map.hpp).
#pragma once

#include <filesystem>
#include <memory>

#include "bgkmap/eval/scored_map.hpp"

namespace bgkmap::eval {

// A .ot (binary = false) or .bt file; throws InputError naming the file (eval/octree_file.hpp).
std::unique_ptr<ScoredMap> load_octree_scored_map(const std::filesystem::path& file, bool binary);

}  // namespace bgkmap::eval
