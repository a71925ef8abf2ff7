// Writing an OctoMap OcTree atomically (shared by the map exports and the octomap method), and the
// comment line that says what a bgkmap .ot holds. Internal: includes OctoMap's headers, so only
// library translation units that already do use it.
#pragma once

#include <octomap/OcTree.h>

#include <filesystem>
#include <optional>
#include <string>

#include "bgkmap/io/map_io.hpp"

namespace bgkmap {

// writeBinary (.bt: max-likelihood states, pruned; changes `tree`) or write (.ot), to a temporary
// file renamed when complete, the resolution printed with round-trip precision. A .ot given a
// `comment` (a line starting with '#', which OctoMap's readers skip) carries it after the first
// line. Throws std::runtime_error naming the file when writing fails.
void write_tree_atomically(const std::filesystem::path& file, octomap::OcTree& tree, bool binary,
                           const std::string& comment = "");

// "# bgkmap ot-values classified" or "... mean": the comment of a .ot bgkmap writes from its maps.
std::string tree_values_comment(TreeValues values);
// The values a header line of that form names; nullopt for any other line.
std::optional<TreeValues> tree_values_in_comment(const std::string& line);

}  // namespace bgkmap
