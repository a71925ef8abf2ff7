// truth.bt through liboctomap: the only simulator file that includes OctoMap.
#include <octomap/OcTree.h>

#include <limits>
#include <stdexcept>

#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/sim/truth.hpp"
#include "io/quiet_stderr.hpp"

namespace bgkmap::sim {

namespace {

// OcTree offers no way to set a node above the finest depth; the rasterizer's cubes are exactly
// such nodes, so they are placed directly (creating the path from the root) instead of being
// expanded into up to 8^16 leaves.
class TruthOcTree : public octomap::OcTree {
 public:
  explicit TruthOcTree(double cell_size) : OcTree(cell_size) {}

  void set_cube(const TruthCube& cube, float log_odds) {
    if (!root) {
      root = new octomap::OcTreeNode();
      ++tree_size;
    }
    const uint32_t offset = 1u << (kTruthLevels - 1);  // OctoMap key = cell index + 2^15
    const uint32_t kx = cube.min.x + offset, ky = cube.min.y + offset, kz = cube.min.z + offset;
    octomap::OcTreeNode* node = root;
    for (int bit = kTruthLevels - 1; bit >= cube.level; --bit) {
      const unsigned child = ((kx >> bit) & 1u) | (((ky >> bit) & 1u) << 1) | (((kz >> bit) & 1u) << 2);
      node = nodeChildExists(node, child) ? getNodeChild(node, child) : createNodeChild(node, child);
    }
    node->setLogOdds(log_odds);
    size_changed = true;
  }
};

}  // namespace

TruthStats write_truth_bt(const std::filesystem::path& file, const Scene& scene, const Box3d& region,
                          double resolution) {
  TruthOcTree tree(resolution);
  const float occupied = tree.getClampingThresMaxLog(), free = tree.getClampingThresMinLog();
  const TruthStats stats =
      rasterize_truth(scene, region, resolution, [&](const TruthCube& c) { tree.set_cube(c, c.occupied ? occupied : free); });
  tree.updateInnerOccupancy();
  write_file_atomically(file, [&](std::ostream& out) {
    out.precision(std::numeric_limits<double>::max_digits10);  // the header's resolution, exactly
    // writeBinary also merges sibling cubes of one state into their parent (prune).
    bool written;
    {
      const QuietStderr quiet;
      written = tree.writeBinary(out);
    }
    if (!written) throw std::runtime_error(file.string() + ": OctoMap could not write the tree");
  });
  return stats;
}

}  // namespace bgkmap::sim
