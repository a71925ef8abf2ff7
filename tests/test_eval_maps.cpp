// The maps `bgkmap eval` scores (src/eval/scored_map.cpp, octree_scored_map.cpp, octree_file.cpp):
// a hand-made OcTree scored as its probabilities computed directly, a .bgk scored exactly as the
// BgkMap was before the abstraction, the .ot export of the same map, and refusal of trees of
// another type and of truncated or corrupt files.
#include <gtest/gtest.h>
#include <octomap/ColorOcTree.h>
#include <octomap/OcTree.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>
#include <vector>

#include "bgkmap/eval/scored_map.hpp"
#include "bgkmap/eval/truth.hpp"
#include "bgkmap/integrate/cpu_integrator.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_io.hpp"
#include "bgkmap/mapper.hpp"
#include "support/test_support.hpp"

namespace bgkmap::eval {
namespace {

constexpr double kResolution = 0.1;

octomap::OcTreeKey key_of(int x, int y, int z) {
  return octomap::OcTreeKey(static_cast<octomap::key_type>(x + 32768), static_cast<octomap::key_type>(y + 32768),
                            static_cast<octomap::key_type>(z + 32768));
}

// Written out, not through OctoMap: p = 1 / (1 + exp(-log_odds)).
double probability_of(float log_odds) { return 1.0 / (1.0 + std::exp(-static_cast<double>(log_odds))); }

// Three single cells and one 2x2x2 group of equal cells that prune() merges into one leaf.
struct HandMadeTree {
  octomap::OcTree tree{kResolution};
  struct Leaf {
    CellIndex cell;
    float log_odds;
  };
  std::vector<Leaf> singles = {{{0, 0, 0}, 2.0f}, {{3, 1, 0}, -1.5f}, {{-2, -1, 1}, 0.25f}};
  CellIndex group_first{4, 4, 2};  // cells 4..5, 4..5, 2..3 share one parent
  float group_log_odds = 1.0f;

  HandMadeTree() {
    for (const Leaf& l : singles) tree.setNodeValue(key_of(l.cell.x, l.cell.y, l.cell.z), l.log_odds);
    for (int i = 0; i < 8; ++i)
      tree.setNodeValue(key_of(group_first.x + (i & 1), group_first.y + ((i >> 1) & 1), group_first.z + (i >> 2)),
                        group_log_odds);
    tree.prune();
  }
  bool in_group(const CellIndex& c) const {
    return c.x >= group_first.x && c.x <= group_first.x + 1 && c.y >= group_first.y && c.y <= group_first.y + 1 &&
           c.z >= group_first.z && c.z <= group_first.z + 1;
  }
};

size_t leaf_count(const octomap::OcTree& tree) {
  size_t n = 0;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) ++n;
  return n;
}

Vec3d centre(const CellIndex& c) { return {(c.x + 0.5) * kResolution, (c.y + 0.5) * kResolution, (c.z + 0.5) * kResolution}; }

// Labels cells by a rule, inside a region.
class RuleTruth : public Truth {
 public:
  RuleTruth(sim::Box3d region, std::function<bool(const CellIndex&)> occupied)
      : region_(region), occupied_(std::move(occupied)) {}
  sim::Box3d region() const override { return region_; }
  TruthLabel label(const CellIndex& c) const override { return occupied_(c) ? TruthLabel::kOccupied : TruthLabel::kFree; }

 private:
  sim::Box3d region_;
  std::function<bool(const CellIndex&)> occupied_;
};


void write_bytes(const std::filesystem::path& file, const std::string& bytes) {
  std::ofstream out(file, std::ios::binary);
  out << bytes;
}

TEST(OctreeScoredMap, HandMadeTreeScoresItsOwnProbabilities) {
  const auto dir = testing::make_temp_dir("eval-maps-ot");
  HandMadeTree made;
  ASSERT_EQ(leaf_count(made.tree), 4u) << "the 2x2x2 group should be one pruned leaf";
  ASSERT_TRUE(made.tree.write((dir / "hand.ot").string()));
  const std::unique_ptr<ScoredMap> map = load_scored_map(dir / "hand.ot");

  EXPECT_DOUBLE_EQ(map->resolution(), kResolution);
  EXPECT_FALSE(map->has_variance());
  EXPECT_DOUBLE_EQ(map->occupied_threshold(), 0.5);  // OctoMap's default: .ot files store none
  for (const auto& leaf : made.singles) {
    const Vec3d p = centre(leaf.cell);
    const MapSample s = map->sample(p.x, p.y, p.z);
    EXPECT_TRUE(s.has_evidence);
    EXPECT_NEAR(s.score, probability_of(leaf.log_odds), 1e-12);
    EXPECT_FALSE(s.variance.has_value());
  }
  for (int i = 0; i < 8; ++i) {  // every cell of the pruned leaf
    const CellIndex c{made.group_first.x + (i & 1), made.group_first.y + ((i >> 1) & 1), made.group_first.z + (i >> 2)};
    const Vec3d p = centre(c);
    EXPECT_NEAR(map->sample(p.x, p.y, p.z).score, probability_of(made.group_log_odds), 1e-12);
  }
  // A neighbour of a known cell, a point far away and one beyond OctoMap's key range: unknown.
  for (const Vec3d& p : {centre({1, 0, 0}), Vec3d{50, 50, 50}, Vec3d{1e4, 0, 0}}) {
    const MapSample s = map->sample(p.x, p.y, p.z);
    EXPECT_FALSE(s.has_evidence);
    EXPECT_EQ(s.score, kUnknownScore);
  }
  // The box around the leaves: cell (-2,-1,1) .. the group's far corner (6, 6, 4) x 0.1 m.
  const sim::Box3d b = map->observed_bounds();
  EXPECT_NEAR(b.min.x, -0.2, 1e-6);
  EXPECT_NEAR(b.min.y, -0.1, 1e-6);
  EXPECT_NEAR(b.min.z, 0.0, 1e-6);
  EXPECT_NEAR(b.max.x, 0.6, 1e-6);
  EXPECT_NEAR(b.max.y, 0.6, 1e-6);
  EXPECT_NEAR(b.max.z, 0.4, 1e-6);

  // Scored against a truth that calls (0,0,0) and the group occupied: the observed cells carry the
  // tree's probabilities, every other cell of the box kUnknownScore.
  const RuleTruth truth({{-1, -1, -1}, {1, 1, 1}},
                        [&](const CellIndex& c) { return c == CellIndex{0, 0, 0} || made.in_group(c); });
  const TruthScores scores = score_against_truth(*map, truth, b);
  std::vector<double> positive = scores.observed_cells.positive, negative = scores.observed_cells.negative;
  std::sort(positive.begin(), positive.end());
  std::sort(negative.begin(), negative.end());
  ASSERT_EQ(positive.size(), 9u);
  for (size_t i = 0; i < 8; ++i) EXPECT_NEAR(positive[i], probability_of(1.0f), 1e-12);
  EXPECT_NEAR(positive[8], probability_of(2.0f), 1e-12);
  ASSERT_EQ(negative.size(), 2u);
  EXPECT_NEAR(negative[0], probability_of(-1.5f), 1e-12);
  EXPECT_NEAR(negative[1], probability_of(0.25f), 1e-12);
  // Cells with centres in the box: x -2..5 (8), y -1..5 (7), z 0..3 (4) = 224.
  EXPECT_EQ(scores.all_cells.positive.size(), 9u);
  ASSERT_EQ(scores.all_cells.negative.size(), 224u - 9u);
  EXPECT_EQ(std::count(scores.all_cells.negative.begin(), scores.all_cells.negative.end(), kUnknownScore), 213);
  std::filesystem::remove_all(dir);
}

TEST(OctreeScoredMap, BinaryTreeHoldsOnlyClampedStates) {
  const auto dir = testing::make_temp_dir("eval-maps-bt");
  HandMadeTree made;
  octomap::OcTree copy(made.tree);  // writeBinary turns a tree into max-likelihood states
  ASSERT_TRUE(copy.writeBinary((dir / "hand.bt").string()));
  const std::unique_ptr<ScoredMap> map = load_scored_map(dir / "hand.bt");
  // Read back at OctoMap's default clamping bounds: occupied 0.971, free 0.1192.
  for (const auto& leaf : made.singles) {
    const Vec3d p = centre(leaf.cell);
    EXPECT_NEAR(map->sample(p.x, p.y, p.z).score, leaf.log_odds > 0 ? 0.971 : 0.1192, 1e-6);
  }
  const Vec3d g = centre(made.group_first);
  EXPECT_NEAR(map->sample(g.x, g.y, g.z).score, 0.971, 1e-6);
  const Vec3d u = centre({1, 0, 0});
  EXPECT_FALSE(map->sample(u.x, u.y, u.z).has_evidence);
  std::filesystem::remove_all(dir);
}

BgkMap build_random_map() {
  BuildParams params;
  params.grid.resolution_m = kResolution;
  params.preprocess.max_range_m = 2.5;
  Mapper mapper(params, std::make_unique<CpuIntegrator>(2));
  for (const Scan& scan : testing::random_scans(11, 3, 300, 1.5f)) mapper.insert(scan);
  return mapper.map();
}

// What eval computed before the abstraction, written out on the BgkMap itself.
sim::Box3d previous_observed_bounds(const BgkMap& map) {
  sim::Box3d box = sim::Box3d::empty();
  const double r = map.grid().resolution();
  for (uint32_t slot = 0; slot < map.block_count(); ++slot)
    for (int local = 0; local < map.cells_per_block(); ++local) {
      if (!map.posterior(map.block_cells(slot)[local]).has_evidence) continue;
      const CellIndex c = map.grid().cell_at(map.key_of_slot(slot), local);
      box.expand(Vec3d{c.x * r, c.y * r, c.z * r});
      box.expand(Vec3d{(c.x + 1) * r, (c.y + 1) * r, (c.z + 1) * r});
    }
  return box;
}

TruthScores previous_scores(const BgkMap& map, const Truth& truth, const sim::Box3d& box) {
  TruthScores out;
  for_each_cell_in(map.grid(), box, [&](const CellIndex& c) {
    const TruthLabel label = truth.label(c);
    if (label == TruthLabel::kUnknown) return;
    const Vec3d p = map.grid().cell_center_d(c);
    const CellPosterior post = map.query(p.x, p.y, p.z);
    const bool occupied = label == TruthLabel::kOccupied;
    (occupied ? out.all_cells.positive : out.all_cells.negative).push_back(post.mean());
    if (post.has_evidence) (occupied ? out.observed_cells.positive : out.observed_cells.negative).push_back(post.mean());
  });
  return out;
}

void expect_same_scores(const TruthScores& a, const TruthScores& b) {
  EXPECT_EQ(a.all_cells.positive, b.all_cells.positive);
  EXPECT_EQ(a.all_cells.negative, b.all_cells.negative);
  EXPECT_EQ(a.observed_cells.positive, b.observed_cells.positive);
  EXPECT_EQ(a.observed_cells.negative, b.observed_cells.negative);
}

TEST(BgkScoredMap, ScoresExactlyAsTheBgkMapDirectly) {
  const auto dir = testing::make_temp_dir("eval-maps-bgk");
  const BgkMap map = build_random_map();
  ASSERT_GT(map.cells_with_evidence(), 1000u);
  const RuleTruth truth({{-1, -1, -1}, {1, 1, 1}}, [](const CellIndex& c) { return (c.x + 2 * c.y + 3 * c.z) % 5 == 0; });
  const sim::Box3d box = previous_observed_bounds(map);
  const TruthScores expected = previous_scores(map, truth, box);
  ASSERT_GT(expected.observed_cells.positive.size(), 100u);
  ASSERT_GT(expected.all_cells.negative.size(), expected.observed_cells.negative.size());

  write_native_map(dir / "m.bgk", map);
  write_octomap_tree(dir / "m.ot", map, TreeValues::kMean);
  const std::unique_ptr<ScoredMap> in_memory = make_scored_map(map);
  const std::unique_ptr<ScoredMap> from_file = load_scored_map(dir / "m.bgk");
  for (const ScoredMap* scored : {in_memory.get(), from_file.get()}) {
    const sim::Box3d b = scored->observed_bounds();
    EXPECT_EQ(b.min.x, box.min.x);
    EXPECT_EQ(b.min.y, box.min.y);
    EXPECT_EQ(b.min.z, box.min.z);
    EXPECT_EQ(b.max.x, box.max.x);
    EXPECT_EQ(b.max.y, box.max.y);
    EXPECT_EQ(b.max.z, box.max.z);
    expect_same_scores(score_against_truth(*scored, truth, box), expected);
    EXPECT_EQ(scored->occupied_threshold(), map.params().classify.occupied_threshold);
    EXPECT_TRUE(scored->has_variance());
  }
  const Vec3d p = map.grid().cell_center_d(map.grid().cell_at(map.key_of_slot(0), 0));
  EXPECT_EQ(in_memory->sample(p.x, p.y, p.z).variance, map.query(p.x, p.y, p.z).variance());

  // The .ot export of the same map: the same cells observed, each mean to float log-odds precision.
  const std::unique_ptr<ScoredMap> tree = load_scored_map(dir / "m.ot");
  const TruthScores from_tree = score_against_truth(*tree, truth, box);
  ASSERT_EQ(from_tree.observed_cells.positive.size(), expected.observed_cells.positive.size());
  ASSERT_EQ(from_tree.observed_cells.negative.size(), expected.observed_cells.negative.size());
  ASSERT_EQ(from_tree.all_cells.negative.size(), expected.all_cells.negative.size());
  for (size_t i = 0; i < expected.observed_cells.negative.size(); ++i)
    ASSERT_NEAR(from_tree.observed_cells.negative[i], expected.observed_cells.negative[i], 1e-6) << i;
  for (size_t i = 0; i < expected.observed_cells.positive.size(); ++i)
    ASSERT_NEAR(from_tree.observed_cells.positive[i], expected.observed_cells.positive[i], 1e-6) << i;
  std::filesystem::remove_all(dir);
}

// Loading `file` must throw an InputError whose one-line message names the file and contains `why`.
void expect_refused(const std::filesystem::path& file, const std::string& why) {
  try {
    load_scored_map(file);
    FAIL() << file << " was accepted";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(file.filename().string()), std::string::npos) << msg;
    EXPECT_NE(msg.find(why), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  }
}

TEST(OctreeFile, RefusesOtherTreesAndCorruptFiles) {
  const auto dir = testing::make_temp_dir("eval-maps-bad");
  HandMadeTree made;
  ASSERT_TRUE(made.tree.write((dir / "good.ot").string()));
  const std::string good = testing::read_bytes(dir / "good.ot");
  ASSERT_NO_THROW(load_scored_map(dir / "good.ot"));

  octomap::ColorOcTree color(kResolution);
  color.updateNode(0.05, 0.05, 0.05, true);
  ASSERT_TRUE(color.write((dir / "color.ot").string()));
  expect_refused(dir / "color.ot", "ColorOcTree, not an OcTree");

  // A tree cut short, and a header followed by bytes whose child flags ask for ever deeper nodes.
  const auto expect_cut_and_deep_refused = [&](const std::string& tree, size_t cut, const std::string& ext) {
    write_bytes(dir / ("truncated" + ext), tree.substr(0, tree.size() - cut));
    expect_refused(dir / ("truncated" + ext), "truncated or corrupt");
    const size_t data = tree.find("data\n") + 5;
    write_bytes(dir / ("deep" + ext), tree.substr(0, data) + std::string(4096, '\xff'));
    expect_refused(dir / ("deep" + ext), "corrupt");
  };
  expect_cut_and_deep_refused(good, 7, ".ot");
  std::string miscounted = good;
  const size_t size_at = miscounted.find("size ");
  miscounted.replace(size_at, miscounted.find('\n', size_at) - size_at, "size 3");
  write_bytes(dir / "miscounted.ot", miscounted);
  expect_refused(dir / "miscounted.ot", "announces 3 nodes");
  write_bytes(dir / "text.ot", "not a tree\n");
  expect_refused(dir / "text.ot", "not an OctoMap tree");
  write_bytes(dir / "empty.ot", "");
  expect_refused(dir / "empty.ot", "not an OctoMap tree");
  expect_refused(dir / "missing.ot", "not found");
  expect_refused(dir / "map.txt", "unknown map format");

  octomap::OcTree copy(made.tree);
  ASSERT_TRUE(copy.writeBinary((dir / "good.bt").string()));
  const std::string good_bt = testing::read_bytes(dir / "good.bt");
  write_bytes(dir / "binary.ot", good_bt);
  expect_refused(dir / "binary.ot", "binary tree");
  expect_cut_and_deep_refused(good_bt, 1, ".bt");
  // A truth .bt goes through the same checks.
  EXPECT_THROW(load_truth(dir / "truncated.bt", make_scored_map(build_random_map())->grid()), InputError);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap::eval
