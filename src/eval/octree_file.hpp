// Reading OctoMap files for eval (maps .ot / .bt, truth .bt). Internal: includes OctoMap.
//
// The bytes are checked before liboctomap reads them: its node readers trust the file, so a
// truncated one leaves them reading uninitialized child bits and a corrupt one recurses deeper
// than the tree's 16 levels (a crash, not an error). Checked: the header (id, size, res, data),
// every node within the file, no node below depth 16, the node count equal to the header's size.
#pragma once

#include <octomap/OcTree.h>

#include <filesystem>
#include <memory>
#include <optional>

#include "bgkmap/io/map_io.hpp"

namespace bgkmap::eval {

enum class OctreeFile {
  kTree,    // .ot: AbstractOcTree::write (full log-odds per node); must hold an OcTree
  kBinary,  // .bt: OcTree::writeBinary (max-likelihood states)
};

// Throws InputError naming the file when it is missing, not of that kind, truncated or corrupt,
// or (kTree) holds another tree type than OcTree. `values`, when given, is set to what a .ot that
// bgkmap wrote says it holds (its "# bgkmap ot-values" comment; nullopt for any other file).
std::unique_ptr<octomap::OcTree> read_octree_file(const std::filesystem::path& file, OctreeFile kind,
                                                  std::optional<TreeValues>* values = nullptr);

}  // namespace bgkmap::eval
