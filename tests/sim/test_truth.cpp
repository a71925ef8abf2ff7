// The truth raster: every cell whose centre is in the region classified exactly once, occupied
// exactly when its centre is inside a solid; and truth.bt holds the same cells.
#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include <array>
#include <cmath>
#include <map>
#include <tuple>
#include <random>
#include <vector>

#include "bgkmap/sim/truth.hpp"
#include "sim/sim_test_util.hpp"
#include "support/test_support.hpp"

namespace bgkmap::sim {
namespace {

struct Region {
  CellIndex lo, hi;
  size_t index(int x, int y, int z) const {
    return (static_cast<size_t>(z - lo.z) * (hi.y - lo.y + 1) + (y - lo.y)) * (hi.x - lo.x + 1) + (x - lo.x);
  }
  size_t cells() const { return index(hi.x, hi.y, hi.z) + 1; }
};

Region cells_of(const Box3d& box, double r) {
  auto first = [&](double v) { return static_cast<int>(std::ceil(v / r - 0.5)); };
  auto last = [&](double v) { return static_cast<int>(std::floor(v / r - 0.5)); };
  return {{first(box.min.x), first(box.min.y), first(box.min.z)}, {last(box.max.x), last(box.max.y), last(box.max.z)}};
}

Scene random_scene(uint32_t seed) {
  std::mt19937 rng(seed);
  Scene scene;
  scene.primitives = testing_support::random_primitives(rng, 2, 1.5);
  return scene;
}

TEST(Truth, RasterEqualsCentreTestOfEveryCell) {
  const double r = 0.1;
  const Box3d box{{-2.03, -1.77, -1.5}, {2.51, 2.2, 1.05}};  // not on cube boundaries
  const Region region = cells_of(box, r);
  for (uint32_t seed : {1u, 2u, 3u}) {
    const Scene scene = random_scene(seed);
    std::vector<int> state(region.cells(), -1);
    size_t outside = 0;
    std::map<std::tuple<int, int, int, int>, std::array<int, 2>> siblings;  // parent -> free/occupied children
    const TruthStats stats = rasterize_truth(scene, box, r, [&](const TruthCube& c) {
      const int n = 1 << c.level;
      const int m = 2 * n;
      auto parent_of = [m](int v) { return v >= 0 ? v / m * m : -((-v + m - 1) / m) * m; };
      ++siblings[{parent_of(c.min.x), parent_of(c.min.y), parent_of(c.min.z), c.level + 1}][c.occupied];
      ASSERT_EQ(c.min.x % n, 0);  // aligned like an octree node
      for (int z = c.min.z; z < c.min.z + n; ++z)
        for (int y = c.min.y; y < c.min.y + n; ++y)
          for (int x = c.min.x; x < c.min.x + n; ++x) {
            if (x < region.lo.x || y < region.lo.y || z < region.lo.z || x > region.hi.x || y > region.hi.y ||
                z > region.hi.z) {
              ++outside;
              continue;
            }
            int& s = state[region.index(x, y, z)];
            ASSERT_EQ(s, -1) << "cell emitted twice";
            s = c.occupied;
          }
    });
    EXPECT_EQ(outside, 0u);
    for (const auto& [parent, counts] : siblings) {  // maximal cubes: OctoMap's prune has nothing to merge
      ASSERT_LT(counts[0], 8);
      ASSERT_LT(counts[1], 8);
    }
    size_t occupied = 0;
    for (int z = region.lo.z; z <= region.hi.z; ++z)
      for (int y = region.lo.y; y <= region.hi.y; ++y)
        for (int x = region.lo.x; x <= region.hi.x; ++x) {
          const int s = state[region.index(x, y, z)];
          ASSERT_NE(s, -1) << "cell never emitted";
          const bool inside = scene.contains({(x + 0.5) * r, (y + 0.5) * r, (z + 0.5) * r});
          ASSERT_EQ(s == 1, inside) << x << " " << y << " " << z;
          occupied += inside;
        }
    EXPECT_EQ(stats.occupied_cells, occupied);
    EXPECT_EQ(stats.occupied_cells + stats.free_cells, region.cells());
    EXPECT_GT(occupied, region.cells() / 20);
    EXPECT_LT(stats.cubes, region.cells() / 3);  // uniform regions come out as large cubes
  }
}

TEST(Truth, RegionMustFitTheOctree) {
  const Scene scene = random_scene(1);
  EXPECT_THROW(rasterize_truth(scene, {{0, 0, 0}, {4000, 1, 1}}, 0.1, [](const TruthCube&) {}), std::invalid_argument);
  EXPECT_NO_THROW(rasterize_truth(scene, {{-3276.8, 0, 0}, {3276.7, 0.1, 0.1}}, 0.1, [](const TruthCube&) {}));
}

TEST(Truth, BtFileHoldsTheSameCells) {
  const double r = 0.1;
  const Box3d box{{-1.6, -1.33, -1.2}, {1.7, 1.6, 0.9}};
  const Region region = cells_of(box, r);
  const Scene scene = random_scene(4);
  const auto dir = bgkmap::testing::make_temp_dir("sim-truth");
  const TruthStats stats = write_truth_bt(dir / "truth.bt", scene, box, r);

  octomap::OcTree tree(1.0);
  ASSERT_TRUE(tree.readBinary((dir / "truth.bt").string()));
  EXPECT_DOUBLE_EQ(tree.getResolution(), r);
  size_t occupied = 0;
  for (int z = region.lo.z - 1; z <= region.hi.z + 1; ++z)
    for (int y = region.lo.y - 1; y <= region.hi.y + 1; ++y)
      for (int x = region.lo.x - 1; x <= region.hi.x + 1; ++x) {
        const octomap::point3d c((x + 0.5) * r, (y + 0.5) * r, (z + 0.5) * r);
        const octomap::OcTreeNode* node = tree.search(c);
        const bool in_region = x >= region.lo.x && y >= region.lo.y && z >= region.lo.z && x <= region.hi.x &&
                               y <= region.hi.y && z <= region.hi.z;
        if (!in_region) {
          ASSERT_EQ(node, nullptr) << "known cell outside the region";
          continue;
        }
        ASSERT_NE(node, nullptr);
        const bool inside = scene.contains({(x + 0.5) * r, (y + 0.5) * r, (z + 0.5) * r});
        ASSERT_EQ(tree.isNodeOccupied(node), inside);
        occupied += inside;
      }
  EXPECT_EQ(stats.occupied_cells, occupied);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap::sim
