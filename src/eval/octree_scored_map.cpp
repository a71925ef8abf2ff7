// An OctoMap OcTree scored by its nodes' probabilities: a leaf (at any depth: pruned leaves cover
// 2^k cells) is a region with evidence; where the tree has no node the score is kUnknownScore.
#include "eval/octree_scored_map.hpp"

#include <octomap/OcTree.h>

#include <cmath>
#include <optional>
#include <utility>

#include "bgkmap/io/errors.hpp"
#include "eval/octree_file.hpp"

namespace bgkmap::eval {

namespace {

class OctreeScoredMap final : public ScoredMap {
 public:
  OctreeScoredMap(std::unique_ptr<octomap::OcTree> tree, std::optional<TreeValues> values)
      : ScoredMap(tree->getResolution()), tree_(std::move(tree)), values_(values) {}

  sim::Box3d observed_bounds() const override {
    sim::Box3d box = sim::Box3d::empty();
    for (auto it = tree_->begin_leafs(), end = tree_->end_leafs(); it != end; ++it) {
      const octomap::point3d c = it.getCoordinate();
      const double half = it.getSize() / 2;
      box.expand(Vec3d{c.x() - half, c.y() - half, c.z() - half});
      box.expand(Vec3d{c.x() + half, c.y() + half, c.z() + half});
    }
    return box;
  }

  MapSample sample(double x, double y, double z) const override {
    MapSample s;
    octomap::OcTreeKey key;
    if (!tree_->coordToKeyChecked(x, y, z, key)) return s;  // beyond the tree's range (search() would print)
    const octomap::OcTreeNode* node = tree_->search(key);
    if (!node) return s;
    s.has_evidence = true;
    s.score = node->getOccupancy();
    return s;
  }

  std::vector<CellIndex> occupied_cells() const override {
    std::vector<CellIndex> cells;
    const double threshold = occupied_threshold(), r = resolution();
    for (auto it = tree_->begin_leafs(), end = tree_->end_leafs(); it != end; ++it) {
      if (!(it->getOccupancy() > threshold)) continue;
      const int32_t side = static_cast<int32_t>(std::lround(it.getSize() / r));  // 2^k for a pruned leaf
      // A solid block wider than 2 cells (a truth tree's ground) holds no thin wall and, expanded,
      // could be more cells than memory holds.
      if (side > 2) continue;
      const auto lowest = [&](double centre) {
        return static_cast<int32_t>(std::floor((centre - it.getSize() / 2) / r + 0.5));
      };
      const CellIndex c{lowest(it.getX()), lowest(it.getY()), lowest(it.getZ())};
      for (int32_t dz = 0; dz < side; ++dz)
        for (int32_t dy = 0; dy < side; ++dy)
          for (int32_t dx = 0; dx < side; ++dx) cells.push_back({c.x + dx, c.y + dy, c.z + dz});
    }
    return cells;
  }

  bool has_variance() const override { return false; }
  double occupied_threshold() const override { return tree_->getOccupancyThres(); }
  bool is_classified_tree() const override { return values_ == TreeValues::kClassified; }

 private:
  std::unique_ptr<octomap::OcTree> tree_;
  std::optional<TreeValues> values_;
};

}  // namespace

std::unique_ptr<ScoredMap> load_octree_scored_map(const std::filesystem::path& file, bool binary) {
  std::optional<TreeValues> values;
  auto tree = read_octree_file(file, binary ? OctreeFile::kBinary : OctreeFile::kTree, &values);
  return std::make_unique<OctreeScoredMap>(std::move(tree), values);
}

double octomap_default_occupied_threshold() { return octomap::OcTree(0.1).getOccupancyThres(); }

}  // namespace bgkmap::eval
