// Writing an OctoMap OcTree atomically (shared by the map exports and the octomap method).
// Internal: includes OctoMap's headers, so only library translation units that already do use it.
#pragma once

#include <octomap/OcTree.h>

#include <filesystem>

namespace bgkmap {

// writeBinary (.bt: max-likelihood states, pruned; changes `tree`) or write (.ot), to a temporary
// file renamed when complete, the resolution printed with round-trip precision. Throws
// std::runtime_error naming the file when writing fails.
void write_tree_atomically(const std::filesystem::path& file, octomap::OcTree& tree, bool binary);

}  // namespace bgkmap
